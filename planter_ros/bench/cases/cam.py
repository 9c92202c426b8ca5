"""Electronic cam rows: the per-cycle evaluation of θ(s), the planned tip sweep against a
brute-force sampled tip path, and one mechanism designed for 0.15 m planting 0.15–0.5 m."""

from __future__ import annotations

from collections.abc import Iterator
import math
import time
from typing import Any

import numpy as np

from planter_ros.cam import CamMechanism, CamTrack, constant_profile, plan_cam, sampled_tip_sweep
from planter_ros.kinematics.five_bar import design_five_bar

from ..registry import BenchContext, Row, Target, bench_case
from ..timing import from_samples

EVAL_TARGET = 20e-6          # cam evaluation ≤ 20 µs per row per SYNC cycle (scalar)
SWEEP_TARGET = 1e-6          # planned tip sweep vs brute force ≤ 1e-6 m
HOLE_TARGET = 1e-4           # the cam's sweep within 0.1 mm of the design hole
TILT_TARGET = math.radians(1.0)
DEPTH, DESIGN_SPACING, HOLE_RATIO = 0.045, 0.15, 0.05     # tomato depth, designed for 0.15 m
SPACINGS = (0.15, 0.2, 0.3, 0.4, 0.5)
SPEED = 0.3
SYNC_PERIOD = 0.01           # s: the command path's default SYNC
EVAL_ERROR_OF = ('max |θ − θ through scipy PPoly of the same coefficients (the vectorised '
                 'path)| over the evaluated distances (rad); θ′ and θ″ in the note')
SWEEP_ERROR_OF = ('max over the profiles |closed-form tip sweep − brute force| (m), the tip '
                  'path sampled at {n:,} points per revolution')
HOLE_ERROR_OF = '|tip sweep − the design hole k·D| (m)'


def _mechanism() -> CamMechanism:
    return CamMechanism.from_design(design_five_bar(DEPTH, DESIGN_SPACING, HOLE_RATIO))


@bench_case('cam evaluation')
def cam_evaluation(ctx: BenchContext) -> Iterator[Row]:
    mech = _mechanism()
    profile = plan_cam(mech, 0.3, SPEED, top_speeds=False).profile
    other = plan_cam(mech, 0.5, SPEED, rule='zero_slip', top_speeds=False).profile
    # one row's travelled distance, SYNC after SYNC at 0.3 m/s, over several plants
    count = ctx.n(2000, 200)
    s = (0.0123 + SPEED * SYNC_PERIOD * np.arange(count)).tolist()
    track = CamTrack(profile)
    track.change(other, s[count // 3])
    x = np.asarray(s)
    references = (
        ('CamProfile.evaluate (θ, θ′, θ″), design-speed cam at d = 300 mm', profile.evaluate,
         [profile.values(x, nu) for nu in range(3)]),
        ('CamTrack.evaluate across a run-time change to zero slip at d = 500 mm',
         track.evaluate, [track.values(x, nu) for nu in range(3)]))
    for what, fn, ref in references:
        t = ctx.measure(lambda: [fn(x) for x in s]).per(count)
        got = np.array([fn(x) for x in s])
        errs = [float(np.max(np.abs(got[:, i] - ref[i]))) for i in range(3)]
        yield Row('cam evaluation', what, 1, 'evaluation', t, error=errs[0],
                  error_of=EVAL_ERROR_OF, targets=[Target('≤ 20 µs', t.median <= EVAL_TARGET)],
                  note=f'{count} SYNC cycles of {SYNC_PERIOD * 1000:g} ms at {SPEED} m/s; '
                       f'θ′ {errs[1]:.1e} rad/m, θ″ {errs[2]:.1e} rad/m²',
                  extra={'errors': errs})


@bench_case('cam tip sweep vs brute force')
def cam_sweep(ctx: BenchContext) -> Iterator[Row]:
    mech = _mechanism()
    samples = 1_000_000          # the target's resolution, quick run or not (< 1 s)
    # --quick: the two ends of the spacings (each plan costs a cam optimisation)
    spacings = ctx.n(SPACINGS, (SPACINGS[0], SPACINGS[-1]))
    cams, constants = [], []
    for d in spacings:
        constants.append(constant_profile(mech, d))
        for rule, speed in (('design_speed', SPEED), ('zero_slip', SPEED), ('zero_slip', 0.5)):
            cams.append(plan_cam(mech, d, speed, rule=rule, top_speeds=False).profile)
    error_of = SWEEP_ERROR_OF.format(n=samples)
    named = ', '.join(f'{d * 1000:.0f}' for d in spacings)
    errors = {}
    brute: list[float] = []         # seconds of each brute-force sweep of the first cams

    def sampled(p: Any) -> float:
        t0 = time.perf_counter()
        sweep = sampled_tip_sweep(p, samples)
        if any(p is c for c in cams[:3]):
            brute.append(time.perf_counter() - t0)
        return sweep
    for name, profiles in (('cam', cams), ('constant speed', constants)):
        errors[name] = max(abs(p.tip_sweep - sampled(p)) for p in profiles)
        n = len(profiles)
        t = ctx.measure(lambda: [p.law.tip_sweep(p.mech) for p in profiles]).per(n)
        laws = sorted({p.law.name.split(' blended')[0] + (' (blended)' if 'blended' in p.law.name
                                                          else '') for p in profiles})
        targets = [Target('err ≤ 1e-6 m', errors[name] <= SWEEP_TARGET)] if name == 'cam' else []
        yield Row('cam tip sweep vs brute force',
                  f'closed form (hole_geometry of the in-soil law), {name}', 1, 'profile', t,
                  error=errors[name], error_of=error_of, targets=targets,
                  note=f'{n} profiles at d = {named} mm: {"; ".join(laws)}; largest sweep '
                       f'{max(p.tip_sweep for p in profiles) * 1000:.2f} mm',
                  extra={'profiles': n, 'samples_per_revolution': samples})
    # --quick: the sweeps of the errors above, timed one by one (not three more rounds)
    t_brute = (from_samples(brute) if ctx.quick else
               ctx.measure(lambda: [sampled_tip_sweep(p, samples) for p in cams[:3]],
                           repeats=3).per(3))
    yield Row('cam tip sweep vs brute force', f'brute force, {samples:,} points per revolution',
              1, 'profile', t_brute, error=max(errors.values()), error_of=error_of,
              extra={'samples_per_revolution': samples})


@bench_case('cam, one mechanism designed for 0.15 m')
def cam_one_mechanism(ctx: BenchContext) -> Iterator[Row]:
    mech = _mechanism()
    hole = mech.design_hole
    # --quick: the two ends of the spacings (each plan is a cam optimisation, timed 5 times)
    for d in ctx.n(SPACINGS, (SPACINGS[0], SPACINGS[-1])):
        t0 = time.perf_counter()
        plan = plan_cam(mech, d, SPEED, top_speeds=False)
        took = time.perf_counter() - t0
        t = ctx.measure(lambda: plan_cam(mech, d, SPEED, top_speeds=False), repeats=3,
                        min_time=0.0)
        p = plan.profile
        f = plan.figures
        sweep, tilt = p.tip_sweep, p.tilt
        const = constant_profile(mech, d)
        cf = const.figures(SPEED)
        t_const = ctx.measure(lambda: constant_profile(mech, d).figures(SPEED), repeats=3,
                              min_time=0.0)
        yield Row('cam, one mechanism designed for 0.15 m',
                  f'd = {d * 1000:.0f} mm, {SPEED} m/s: cam ({p.law.name})', 1, 'plan', t,
                  error=abs(sweep - hole), error_of=HOLE_ERROR_OF,
                  targets=[Target('sweep within 0.1 mm', abs(sweep - hole) <= HOLE_TARGET),
                           Target('tilt ≤ 1°', abs(tilt) <= TILT_TARGET),
                           Target('within the default limits', plan.feasible)],
                  note=_figures_note(sweep, tilt, f) + f'; first plan {took * 1000:.0f} ms',
                  extra={'spacing': d, 'tip_sweep': sweep, 'tilt': tilt,
                         'loads': f.as_dict()})
        yield Row('cam, one mechanism designed for 0.15 m',
                  f'd = {d * 1000:.0f} mm, {SPEED} m/s: constant speed', 1, 'profile', t_const,
                  error=abs(const.tip_sweep - hole), error_of=HOLE_ERROR_OF,
                  note=_figures_note(const.tip_sweep, const.tilt, cf),
                  extra={'spacing': d, 'tip_sweep': const.tip_sweep, 'tilt': const.tilt,
                         'loads': cf.as_dict()})


def _figures_note(sweep: float, tilt: float, f: Any) -> str:
    return (f'sweep {sweep * 1000:.4f} mm, tilt {math.degrees(tilt):+.2f}°, peak ω '
            f'{f.peak_speed:.3g} rad/s, α {f.peak_acceleration:.3g} rad/s², jerk '
            f'{f.peak_jerk:.3g} rad/s³, motor torque {f.peak_torque:.3g} N·m peak / '
            f'{f.rms_torque:.3g} RMS; {"within" if f.feasible else "BEYOND"} the limits '
            f'({f.binding} {f.utilisation[f.binding] * 100:.0f} %)')
