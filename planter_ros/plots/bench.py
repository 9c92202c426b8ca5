"""Error against run time (log-log) for the bench methods that trade one for the other."""

from matplotlib.figure import Figure

from planter_ros.bench.host import machine_line
from planter_ros.bench.registry import Row

ERROR_FLOOR = 1e-18   # an exact 0 error is drawn here (log axes), marked in the legend


def plot_tradeoff(machine, rows, path):
    """One series per row.series (e.g. dense sampling at growing sample counts)."""

    # series name -> (run time per item s, error, row) of each row that has both
    series: dict[str, list[tuple[float, float, Row]]] = {}
    for r in rows:
        if r.series and r.status == 'ok' and r.error is not None and r.per_item:
            series.setdefault(r.series, []).append((r.per_item, r.error, r))
    fig = Figure(figsize=(9, 6))
    ax = fig.subplots()
    markers = 'osD^v<>ph*'
    for i, (name, members) in enumerate(sorted(series.items())):
        members.sort(key=lambda member: member[0])
        x = [per_item for per_item, _, _ in members]
        y = [max(error, ERROR_FLOOR) for _, error, _ in members]
        ax.plot(x, y, marker=markers[i % len(markers)], ls='-' if len(members) > 1 else '',
                label=name)
        for (_, _, r), xi, yi in zip(members, x, y):
            if 'samples' in r.extra:
                ax.annotate(f"{r.extra['samples']:,} samples", (xi, yi),
                            textcoords='offset points', xytext=(5, 5), fontsize=8)
    ax.set_xscale('log')
    ax.set_yscale('log')
    ax.axhline(1e-9, color='gray', ls=':', label='accuracy target 1e-9')
    ax.set(xlabel='run time per item (s, median)',
           ylabel=f'max relative error vs mpmath (0 drawn at {ERROR_FLOOR:g})',
           title='planter bench: error against run time (down-left is better; the dotted '
                 'line is the accuracy target)')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8, loc='best')
    fig.text(0.01, 0.01, machine_line(machine), fontsize=7, color='gray')
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path, dpi=110)
    return path
