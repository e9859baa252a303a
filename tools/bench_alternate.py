#!/usr/bin/env python3
"""Compares two builds of the benchmark suite on a noisy host: runs BEFORE and AFTER in
alternating order (ABBA...), each pinned to core 1, and prints each benchmark's median
real time per build, their ratio (AFTER / BEFORE) and the fastest run of each.

Usage: tools/bench_alternate.py BEFORE AFTER FILTER ROUNDS
  BEFORE, AFTER  two tearables_bench binaries (copy one aside before rebuilding)
  FILTER         a --benchmark_filter regular expression
  ROUNDS         runs of each binary
"""
import json
import statistics
import subprocess
import sys


def run(binary, pattern):
    out = subprocess.run(["taskset", "-c", "1", binary, "--benchmark_filter=" + pattern, "--benchmark_format=json"],
                         capture_output=True, text=True, check=True).stdout
    return {bm["name"]: bm["real_time"] for bm in json.loads(out)["benchmarks"]}


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    before, after, pattern, rounds = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    times = {before: {}, after: {}}
    for r in range(rounds):
        for binary in (before, after) if r % 2 == 0 else (after, before):
            for name, t in run(binary, pattern).items():
                times[binary].setdefault(name, []).append(t)
    print(f"{'benchmark':70s} {'before':>10s} {'after':>10s} {'ratio':>7s}")
    for name, a in times[before].items():
        b = times[after].get(name)
        if not b:
            continue
        ma, mb = statistics.median(a), statistics.median(b)
        print(f"{name:70s} {ma:10.4g} {mb:10.4g} {mb / ma:7.3f}   min {min(a):.4g} / {min(b):.4g}")


if __name__ == "__main__":
    main()
