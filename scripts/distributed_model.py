#!/usr/bin/env python3
"""Predicted time per fit iteration of `mpirun -np N relume fit` (docs/design/distributed.md).

    T(N) = W / (N c) + R + X(N),   X(N) = E * alpha * ceil(log2 N) + S * (N - 1) / N / beta

W: core-seconds of tracing per iteration (split between the ranks; applying the splats is counted
in it), c: cores per rank, R: seconds every rank spends on the same work (batch sampling, loss,
optimiser step), S: bytes all ranks exchange per iteration together, E: exchanges per iteration, alpha:
network latency, beta: bandwidth. The defaults are the demo room's albedo stage at the default
batch (B = 8192), measured on 2 cores (docs/notes/2026-11-28-fit-over-mpi.md).
"""
import argparse
import math


def iteration_seconds(n, a):
    exchange = 0.0 if n == 1 else a.exchanges * a.latency * math.ceil(math.log2(n)) + \
        a.bytes * (n - 1) / n / a.bandwidth
    return a.work / (n * a.cores) + redundant(n, a) + exchange


def redundant(n, a):
    return a.redundant / n if a.split_redundant else a.redundant


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--work", type=float, default=0.431, help="W, core-seconds of tracing per iteration")
    p.add_argument("--redundant", type=float, default=0.012, help="R, seconds per iteration on every rank")
    p.add_argument("--bytes", type=float, default=4.0e6, help="S, bytes exchanged per iteration, all ranks")
    p.add_argument("--exchanges", type=int, default=8, help="E, collective calls per iteration")
    p.add_argument("--cores", type=int, default=2, help="c, cores (threads) per rank")
    p.add_argument("--latency", type=float, default=10e-6, help="alpha, seconds (25 Gb/s Ethernet: ~10 us)")
    p.add_argument("--bandwidth", type=float, default=25e9 / 8, help="beta, bytes per second")
    p.add_argument("--scale", type=float, default=1.0,
                   help="the batch (and so W, R and S) this many times the default's: weak scaling")
    p.add_argument("--split-redundant", action="store_true",
                   help="what if the sampling and the step were split between the ranks too (not built)")
    p.add_argument("--ranks", default="1,2,8,64,512")
    a = p.parse_args()
    a.work *= a.scale
    a.redundant *= a.scale
    a.bytes *= a.scale
    t1 = iteration_seconds(1, a)
    print("| ranks | cores | ms per iteration | speed-up | parallel efficiency | exchange share |")
    print("| --- | --- | --- | --- | --- | --- |")
    for n in (int(x) for x in a.ranks.split(",")):
        t = iteration_seconds(n, a)
        x = t - a.work / (n * a.cores) - redundant(n, a)
        print(f"| {n} | {n * a.cores} | {1e3 * t:.1f} | {t1 / t:.1f} | {t1 / t / n:.0%} | {x / t:.0%} |")
    if not a.split_redundant:
        print(f"trace time equals the redundant time at N = {a.work / (a.cores * a.redundant):.0f} ranks")


if __name__ == "__main__":
    main()
