"""Three-arm figures: closure accuracy and time per method against an mpmath reference, build
time, and the time of one full cycle of all three arms. `python -m planter_ros.bench.three_arm`.
"""

import math
import statistics
import time
from pathlib import Path

SCENE = Path(__file__).resolve().parents[2] / 'config' / 'rice_three_arm.yaml'


def _median_time(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def measure(scene=SCENE, repeat=200):
    import mpmath

    from planter_ros.kinematics.three_arm import (
        PitchCurve, ThreeArmMechanism, solve_centre_distance)
    from planter_ros.scene import load_scene

    params = load_scene(scene)
    curve = PitchCurve(params['control_radii'], params['control_angles'],
                       params.get('interpolant', 'periodic_cubic'))
    ends = [float(e) for e in curve.pieces]
    mpmath.mp.dps = 30

    def mean_ratio(a):
        a = mpmath.mpf(a)
        total = mpmath.fsum(mpmath.quad(lambda t: (lambda r: r / (a - r))(
            mpmath.mpf(float(curve(float(t))))), [ends[i], ends[i + 1]])
            for i in range(len(ends) - 1))
        return total / (2 * mpmath.pi)

    a_ref = mpmath.findroot(lambda a: mean_ratio(a) - 1, solve_centre_distance(curve).a)
    out = {'reference_centre_distance': float(a_ref), 'closure': []}
    for method, kw in (('gauss', {}), ('trapezoid', {'samples': 360}),
                       ('trapezoid', {'samples': 4096}), ('paper', {})):
        closure = solve_centre_distance(curve, method, **kw)
        seconds = _median_time(lambda: solve_centre_distance(curve, method, **kw), 30)
        out['closure'].append({
            'method': method + (f" n={kw['samples']}" if kw else ''),
            'centre_distance': closure.a,
            'relative_error': float(abs(closure.a - a_ref) / a_ref),
            'closure_residual': float(abs(mean_ratio(closure.a) - 1)),
            'samples': closure.evaluations, 'seconds': seconds})
    out['build_seconds'] = _median_time(lambda: ThreeArmMechanism.from_parameters(params), 30)
    mech = ThreeArmMechanism.from_parameters(params)
    for n in (360, 3600):
        out[f'cycle_{n}_seconds'] = _median_time(lambda: mech.cycle(n), repeat)
    return out


def main():
    r = measure()
    print(f"closure reference a = {r['reference_centre_distance'] * 1e3:.12f} mm "
          '(mpmath, 30 digits)')
    print(f"{'method':<18}{'a (mm)':>20}{'rel. error':>12}{'residual':>12}{'samples':>9}"
          f"{'time':>11}")
    for c in r['closure']:
        print(f"{c['method']:<18}{c['centre_distance'] * 1e3:>20.12f}{c['relative_error']:>12.2e}"
              f"{c['closure_residual']:>12.2e}{c['samples']:>9d}{c['seconds'] * 1e6:>9.0f} µs")
    print(f"build (spline, closure, gear maps): {r['build_seconds'] * 1e3:.2f} ms")
    for n in (360, 3600):
        print(f"one cycle, 3 arms × {n} angles: {r[f'cycle_{n}_seconds'] * 1e6:.0f} µs")


if __name__ == '__main__':
    main()
