"""Real-time factor of the fixed nucleo-f746 scenario (same as `mcusim bench nucleo-f746`).

    python benchmarks/bench_nucleo.py [--duration 1s] [--repeat 3]

Speed is measured here, never in tests. Report the median with its min/max spread: the machine's
noise (other jobs on the 2 cores) moves single runs by 10-20 %.
"""

import argparse

from mcusim.bench import bench
from mcusim.time import parse_duration

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", default="1s")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    r = bench("nucleo-f746", parse_duration(a.duration), a.repeat)
    for k, v in r.items():
        print(f"{k:>20}: {v}")
