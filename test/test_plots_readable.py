"""Every figure the product writes answers its question at a glance: each panel has a title and
both axes a label with its unit (or a count), no two labels or titles overlap, every legend
stays inside its panel, and the targets a reader judges against are drawn (the design hole on
the five-bar and replay figures, the goal ranges on the three-arm one)."""
import contextlib
import io

import pytest

from cli_helpers import REPO, planter_here

from planter_ros.cli.main import main

SAMPLE = str(REPO / 'bags' / 'sample_pepper_stall.mcap')
COMMANDS = {
    'five-bar': ['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', '--method',
                 'paper'],
    'three-arm': ['design', 'three-arm', '--params', str(REPO / 'config' / 'rice_three_arm.yaml')],
    'replay': ['replay', SAMPLE],
    'cam': ['cam', 'five-bar', '--depth', '0.045', '--design-spacing', '0.2', '--spacing',
            '0.15,0.3', '--speed', '0.3'],
    'bench': ['bench', '--quick', '--only', 'hole width'],
}
COUNTS = ('plants',)              # axes whose quantity is a count: no unit


@pytest.fixture(scope='module')
def figures(tmp_path_factory):
    """{name: (figure, text printed)} of each command's --plot: the figure it saved, kept for
    inspection."""
    # matplotlib loaded here, not at collection, which every test process does (half a second)
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib.figure import Figure
    out = {}
    saved = []
    save = Figure.savefig

    def save_and_keep(fig, *args, **kwargs):
        saved.append(fig)
        return save(fig, *args, **kwargs)

    Figure.savefig = save_and_keep
    try:
        for name, args in COMMANDS.items():
            saved.clear()
            path = tmp_path_factory.mktemp(name) / f'{name}.png'
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                assert main([*args, '--plot', str(path)]) in (0, 1)
            assert path.stat().st_size > 10_000
            out[name] = (saved[-1], printed.getvalue())
    finally:
        Figure.savefig = save
    yield out


def panels(fig):
    """The figure's data panels (not colour bars, not the twin of a panel, not blank)."""
    out = []
    for ax in fig.axes:
        twin = any(ax.get_position().bounds == other.get_position().bounds for other in out)
        if ax.axison and ax.get_label() != '<colorbar>' and not twin:
            out.append(ax)
    return out


@pytest.mark.slow                 # the figures fixture: every command's --plot
@pytest.mark.parametrize('name', sorted(COMMANDS))
def test_every_panel_says_what_it_shows_with_units(figures, name):
    fig, _ = figures[name]
    for ax in panels(fig):
        title = ax.get_title() or ax.get_title('left') or ax.get_title('right')
        assert title.strip(), f'{name}: a panel without a title'
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            assert label.strip(), f'{name}: panel {title!r} has an axis without a label'
            assert any(c in label for c in '([') or label in COUNTS, \
                f'{name}: {title!r}: axis label {label!r} has no unit'


@pytest.mark.parametrize('name', sorted(COMMANDS))
def test_no_labels_overlap_and_legends_stay_inside(figures, name):
    fig, _ = figures[name]
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    texts = [t for t in [fig._suptitle] if t is not None and t.get_text()]
    for ax in panels(fig):
        texts += [t for t in (ax.title, ax._left_title, ax._right_title, ax.xaxis.label,
                              ax.yaxis.label) if t.get_text()]
    text_apart_and_legends_inside(name, fig, canvas, texts)


def text_apart_and_legends_inside(name, fig, canvas, texts):
    """Every panel's legend inside its panel; no two of `texts` overlap, none cut off at the
    figure's left or right edge (`canvas`: the figure's, drawn)."""
    renderer = canvas.get_renderer()
    for ax in panels(fig):
        legend = ax.get_legend()
        if legend is not None:
            box, frame = legend.get_window_extent(renderer), ax.get_window_extent(renderer)
            assert (box.x0 >= frame.x0 - 1 and box.x1 <= frame.x1 + 1
                    and box.y0 >= frame.y0 - 1 and box.y1 <= frame.y1 + 1), \
                f'{name}: the legend of {ax.get_title()!r} leaves its panel'
    width, _ = canvas.get_width_height()
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in texts]
    for i, (a, box_a) in enumerate(boxes):
        for b, box_b in boxes[i + 1:]:
            assert not box_a.overlaps(box_b), f'{name}: {a!r} overlaps {b!r}'
        assert box_a.x0 >= -1 and box_a.x1 <= width + 1, f'{name}: {a!r} is cut off'


def test_the_targets_are_drawn(figures):
    def legend_texts(fig):
        return ' '.join(t.get_text() for ax in fig.axes if ax.get_legend()
                        for t in ax.get_legend().get_texts())
    assert 'design hole k·D' in legend_texts(figures['five-bar'][0])
    assert 'design hole' in legend_texts(figures['replay'][0])
    assert 'on d (target)' in legend_texts(figures['replay'][0])
    titles = ' '.join(ax.get_title() for ax in figures['three-arm'][0].axes)
    assert 'goal ≥ 2.5 mm' in titles and 'goal ≥ 260 mm' in titles
    assert 'accuracy target' in legend_texts(figures['bench'][0])
    assert 'limit (100 %)' in legend_texts(figures['cam'][0])


# ------------------------------------------------------------------------- the season report

@pytest.fixture(scope='module')
def season_figures(tmp_path_factory):
    """The figures of `planter analyze`'s season report (plots.season) and their canvases, kept
    as drawn: a season of a 4-row and a 1-row run (five rows: two lines of histograms)."""
    import matplotlib
    matplotlib.use('Agg')
    from planter_ros.plots import season
    from planter_ros.sim.season import simulate_bag
    root = tmp_path_factory.mktemp('season')
    simulate_bag(root / 'a.mcap', 3, 0, 8.0, 4)
    simulate_bag(root / 'b.mcap', 3, 1, 8.0, 1)
    kept = []
    png = season._png

    def keep(fig):
        kept.append((fig, fig.canvas))               # (closed, a figure loses its canvas)
        return png(fig)
    season._png = keep
    try:
        done = planter_here('analyze', root, '--out', root / 'tables', '--workers', 1)
        assert done.returncode == 0, done.stderr[-2000:]
    finally:
        season._png = png
    assert (root / 'tables' / 'report.html').is_file()
    return kept


def test_the_season_reports_figures_keep_their_text_apart_and_inside(season_figures):
    """Maps (one per run), the spacing histograms, the trends: every panel has a title, no two
    labels or titles overlap (a title under the axis label of the panel above it neither),
    every legend stays inside its panel, nothing (tick labels, colour bars) is cut off at the
    figure's edge."""
    titles = [ax.get_title() for fig, _ in season_figures for ax in panels(fig)]
    assert sum('tilt' in t for t in titles) == 2 and sum('spacings' in t for t in titles) == 5
    assert 'quality of feed [%]' in titles
    for fig, canvas in season_figures:
        renderer = canvas.get_renderer()              # as the report drew it (plots.season)
        width, height = canvas.get_width_height()
        texts = []
        for ax in fig.axes:
            if ax.axison:
                box = ax.get_tightbbox(renderer)
                assert (box.x0 >= 0 and box.x1 <= width and box.y0 >= 0
                        and box.y1 <= height), f'{ax.get_title()!r} is cut off'
        for ax in panels(fig):
            assert ax.get_title().strip(), 'a panel without a title'
            texts += [t for t in (ax.title, ax.xaxis.label, ax.yaxis.label) if t.get_text()]
        text_apart_and_legends_inside('season report', fig, canvas, texts)
