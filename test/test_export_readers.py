"""Every output of `planter replay` on a bag with empty cups, doubles, unknown tilt and input
gaps, read back with the reader a user has: the Shapefile through GDAL (pyogrio, Arrow: nulls
as nulls), the GeoJSON through json and GDAL, the CSV through pandas and DuckDB. An undefined
value of the replay (NaN) is null in every one of them, a defined one is its value; the plot is
drawn; an output that fails is named and never keeps the others from being written
(doc/exports.md, doc/planting_quality.md)."""
import contextlib
import io
import json
import math

import numpy as np
import pytest

from planter_ros.cli.main import main
from planter_ros.recording.replay import replay
from planter_ros.sim.season import simulate_bag
from planter_ros.sim.tray import TrayShares


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """A 4-row season bag whose tray has many empty cells and doubles (20 s)."""
    path = tmp_path_factory.mktemp('readers') / 'gappy.mcap'
    simulate_bag(path, 0, 0, 20.0, 4, TrayShares(0.15, 0.08))
    return path


@pytest.fixture(scope='module')
def result(bag):
    r = replay(str(bag))
    p = r.plants
    # the cases this module is about are all in the bag
    assert r.summary['instants']['empty'] > 0 and r.summary['instants']['double'] > 0
    assert np.isnan(p.tilt).any() and np.isnan(p.upright).any()
    assert (p.input_gap == 1).any() and np.isnan(p.spacing).any()
    return r


@pytest.fixture(scope='module')
def outputs(bag, result, tmp_path_factory):
    out = tmp_path_factory.mktemp('outputs')
    files = {'plot': out / 'replay.png', 'geojson': out / 'plants.geojson',
             'csv': out / 'plants.csv', 'shapefile': out / 'plants.shp',
             'isoxml': out / 'TASKDATA'}
    code, stdout, stderr = run_cli(['replay', bag] + [x for option, path in files.items()
                                                      for x in (f'--{option}', path)])
    assert code == 0, stderr
    for option, path in files.items():
        assert path.exists(), option
    return files


def run_cli(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def nulls(values):
    """Which values are null: None, NaN or pandas' NA (a nullable integer column)."""
    import pandas as pd
    return np.array([v is None or v is pd.NA or (isinstance(v, float) and math.isnan(v))
                     for v in values])


def check_column(read, expected, name, tolerance=5e-7, relative=0.0):
    """`read` (a reader's values, None/NaN for null) against the replay's (NaN: undefined)."""
    expected = np.asarray(expected, dtype=float)
    missing = nulls(read)
    assert np.array_equal(missing, np.isnan(expected)), name
    got = np.array([np.nan if m else float(v) for v, m in zip(read, missing)])
    assert np.allclose(got[~missing], expected[~missing], atol=tolerance, rtol=relative), name


FIELDS = ('spacing', 'spacing_error', 'hole_width', 'tilt', 'upright')


def test_the_plot_is_drawn_with_unknown_tilts(outputs):
    import matplotlib.image
    image = matplotlib.image.imread(outputs['plot'])
    assert image.shape[0] >= 800 and image.shape[1] >= 1200


def test_the_shapefile_holds_nulls_as_gdal_reads_them(outputs, result):
    """GDAL (pyogrio's Arrow reader, which keeps nulls): an unknown upright is null, not False
    (a blank logical cell reads False), a number without a value is null."""
    from pyogrio import raw
    _, table = raw.read_arrow(str(outputs['shapefile']))
    columns = table.to_pydict()
    p = result.plants
    names = {'spacing': 'spacing_m', 'spacing_error': 'sp_err_m', 'hole_width': 'hole_w_m',
             'tilt': 'tilt_rad', 'upright': 'upright'}
    for field in FIELDS:
        check_column(columns[names[field]], getattr(p, field), field)
    assert sum(v is None for v in columns['upright']) == np.isnan(p.upright).sum() > 0
    assert [bool(v) for v in columns['input_gap']] == [bool(v) for v in p.input_gap == 1]
    # the numpy reader (what GeoPandas gives) reads the unknown logical as NaN, not False
    _, _, _, values = raw.read(str(outputs['shapefile']), columns=['upright'])
    assert np.array_equal(np.isnan(values[0].astype(float)), np.isnan(p.upright))


def test_the_geojson_holds_nulls_for_json_and_gdal(outputs, result):
    from pyogrio import raw
    features = json.loads(outputs['geojson'].read_text())['features']
    p = result.plants
    for field in FIELDS:
        check_column([f['properties'][field] for f in features], getattr(p, field), field,
                     tolerance=0.0)
    assert all(isinstance(f['properties']['upright'], bool) or f['properties']['upright'] is None
               for f in features)
    _, table = raw.read_arrow(str(outputs['geojson']))
    columns = table.to_pydict()
    for field in FIELDS:
        check_column(columns[field], getattr(p, field), f'GDAL {field}', tolerance=0.0)


def test_the_csv_names_its_units_and_holds_nulls_for_pandas_and_duckdb(outputs, result):
    import duckdb
    import pandas as pd
    header = outputs['csv'].read_text().splitlines()[0].split(',')
    assert header == ['row', 'row_name', 'index', 'time_s', 'longitude_deg', 'latitude_deg',
                      'spacing_m', 'spacing_error_m', 'hole_width_m', 'tilt_rad', 'upright',
                      'status', 'reason', 'input_gap']
    p = result.plants
    names = {'spacing': 'spacing_m', 'spacing_error': 'spacing_error_m',
             'hole_width': 'hole_width_m', 'tilt': 'tilt_rad', 'upright': 'upright'}
    frame = pd.read_csv(outputs['csv'])
    duck = duckdb.sql(f"SELECT * FROM read_csv('{outputs['csv']}')").df()
    for reader, table in (('pandas', frame), ('duckdb', duck)):
        for field in FIELDS:
            # (pandas' fast float parser is within 1 ulp or so of the decimal text)
            check_column(table[names[field]].tolist(), getattr(p, field), f'{reader} {field}',
                         tolerance=1e-15, relative=1e-14)
        assert table['time_s'].tolist() == pytest.approx(p.time.tolist(), abs=1e-6)
    assert sorted(frame['status'].unique()) == sorted(
        {'planted', 'empty', 'double'} & set(frame['status']))
    assert (frame['status'] == 'empty').sum() == result.summary['instants']['empty']


def test_a_failed_output_is_named_and_the_others_are_written(bag, tmp_path, monkeypatch):
    """The plot fails (as it did on NaN tilts): exit 1, one line naming --plot, and the CSV,
    GeoJSON, Shapefile and ISOXML asked for with it are all written."""
    import planter_ros.plots.replay

    def broken(result, path):
        raise ValueError('cannot convert float NaN to integer')
    monkeypatch.setattr(planter_ros.plots.replay, 'plot_replay', broken)
    files = {'plot': tmp_path / 'r.png', 'csv': tmp_path / 'p.csv',
             'geojson': tmp_path / 'p.geojson', 'shapefile': tmp_path / 'p.zip',
             'isoxml': tmp_path / 'td.zip'}
    code, out, err = run_cli(['replay', bag] + [x for option, path in files.items()
                                                for x in (f'--{option}', path)])
    assert code == 1
    assert err.count('planter: error:') == 1 and '--plot' in err and 'NaN' in err
    assert not files['plot'].exists()
    for option in ('csv', 'geojson', 'shapefile', 'isoxml'):
        assert files[option].is_file(), option
    assert 'CSV written' in out and 'ISOXML written' in out
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for k, p in files.items() if k != 'plot')          # no temporary left
