"""Replay speed benchmark: a generated 10-minute bag, replayed; prints msgs/s and × real time.

`python -m planter_ros.recording.benchmark [--duration S]` (the bag goes to a temporary
directory and is deleted). `planter bench` can call `replay_benchmark()`.
"""

import tempfile
import time
from pathlib import Path


def replay_benchmark(duration=600.0, repeats=3):
    """Median replay time of a generated bag of `duration` s; returns a dict of figures."""
    from planter_ros.recording.replay import replay
    from planter_ros.recording.samples import (five_bar_design_message, simulate_run,
                                               write_input_bag)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'bench.mcap'
        run = simulate_run(five_bar_design_message(), duration=duration)
        rec = write_input_bag(run, path)
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            result = replay(path)
            times.append(time.perf_counter() - start)
        elapsed = sorted(times)[len(times) // 2]
        used = result.messages['ground_speed'] + result.messages['joint_states']
        return {
            'bag_duration_s': result.duration,
            'bag_messages': rec.message_count,
            'bag_bytes': path.stat().st_size,
            'messages_used': used,
            'plants': result.summary['plants'],
            'replay_s': elapsed,
            'messages_per_s': rec.message_count / elapsed,
            'used_messages_per_s': used / elapsed,
            'times_real_time': result.duration / elapsed,
        }


def main(argv=None):
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=600.0, help='bag length (s)')
    args = parser.parse_args(argv)
    r = replay_benchmark(args.duration)
    print(f'replay of a {r["bag_duration_s"]:.0f} s bag ({r["bag_messages"]} messages, '
          f'{r["bag_bytes"] / 1e6:.2f} MB, {r["plants"]} plants): {r["replay_s"] * 1e3:.0f} ms '
          f'median of 3 = {r["times_real_time"]:.0f}x real time, '
          f'{r["messages_per_s"] / 1e3:.0f} k bag msgs/s '
          f'({r["used_messages_per_s"] / 1e3:.0f} k decoded input msgs/s)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
