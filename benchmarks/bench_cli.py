"""Start-up time of the command line: --help, a command's --help and an argument error.

Target: each under 0.3 s wall (issue 17), measured as the median of several runs of a
fresh interpreter. The baseline is the bare interpreter (``python -c pass``) in the same
run, so the ratio shows what the package adds. ``--quick`` runs each case 3 times.

    python benchmarks/bench_cli.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

TARGET = 0.3  # [s] wall, per invocation
CASES = {
    "bare interpreter (baseline)": ["-c", "pass"],
    "youbot-opt --help": ["-m", "youbot_opt", "--help"],
    "youbot-opt ikpath --help": ["-m", "youbot_opt", "ikpath", "--help"],
    "youbot-opt solve --help": ["-m", "youbot_opt", "solve", "--help"],
    "youbot-opt report --help": ["-m", "youbot_opt", "report", "--help"],
    "youbot-opt solve --bogus (error)": ["-m", "youbot_opt", "solve", "--bogus"],
}


def _time(args: list[str], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        tic = time.perf_counter()
        subprocess.run([sys.executable, *args], capture_output=True, check=False)
        times.append(time.perf_counter() - tic)
    return statistics.median(times)


def main() -> int:
    """Time each case and print it against the target; exit 1 if a case misses it."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 runs per case instead of 10")
    repeat = 3 if parser.parse_args().quick else 10
    base = _time(CASES["bare interpreter (baseline)"], repeat)
    missed = 0
    print(f"{'case':<36}{'median [s]':>12}{'x baseline':>12}  target {TARGET} s")
    for name, args in CASES.items():
        t = base if args == ["-c", "pass"] else _time(args, repeat)
        ok = t < TARGET
        missed += not ok
        print(f"{name:<36}{t:>12.3f}{t / base:>12.1f}  {'ok' if ok else 'MISSED'}")
    return 1 if missed else 0


if __name__ == "__main__":
    raise SystemExit(main())
