"""The demo prints two spacing errors for one run, its own and replay's of its bag: they share
one definition (signed mean, sigma, max |error|) and each says where its plants are placed (the
simulator's true travelled distance; the distance integrated from the recorded ground speed),
so a user comparing them knows why they differ."""
import numpy as np

from planter_ros.prediction import PLANT_FIELDS, Plants, summarize
from planter_ros.recording.replay import replay
from planter_ros.recording.replay_text import format_summary
from planter_ros.sim.spacing import error_figures

from cli_helpers import REPO


def test_the_demo_figures_are_replays_definitions():
    errors = np.random.default_rng(3).normal(0.001, 0.004, 40)
    errors[5] = np.nan                          # the first plant of a bag has no gap
    plants = Plants.from_table(np.zeros((errors.size, len(PLANT_FIELDS))))
    plants.spacing_error = errors
    s = summarize(plants, 0.2)
    mean, sigma, worst, rms = error_figures(errors)
    assert (mean, sigma, worst) == (s['spacing_error_mean'], s['spacing_error_std'],
                                    s['spacing_error_max'])
    assert abs(rms ** 2 - (mean ** 2 + sigma ** 2)) < 1e-15
    assert error_figures([np.nan]) == (None, None, None, None)


def test_replay_says_where_its_plants_are():
    text = format_summary(replay(REPO / 'bags' / 'sample_tomato.mcap'))
    line = next(x for x in text.splitlines() if x.startswith('spacing error'))
    assert 'recorded ground speed' in line and 'sigma' in line and 'max |error|' in line
