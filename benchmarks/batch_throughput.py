"""Throughput of batch meshing: serial, then Dask LocalClusters of 1, 2, ... worker processes.

    python benchmarks/batch_throughput.py                  # 1000 plates of about 200 nodes
    python benchmarks/batch_throughput.py --count 100 --workers 1 2

Every mode meshes the same specs (``random_specs("plates", count, seed=0, nodes=200)``: paper-size
meshes, 95-309 nodes in the paper's Section 5) into its own directory; the table gives meshes per
second, the speed-up over serial and the scheduling overhead per mesh (wall time on one worker
minus wall time in this process, and wall time on one worker minus the time spent inside the
mesh tasks, each divided by the number of meshes: what going through Dask costs).  Cluster
start-up is timed separately and left out of the throughput.  The modes take turns on a tenth
of the specs at a time (``--rounds``), so that the changing load of a shared machine weighs on
all of them alike.  The files of every mode are compared at the end: they must be identical,
bit for bit.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import os
import tempfile
import time
from pathlib import Path

from injmesh.batch import mesh_many, random_specs


def file_hashes(out: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(out.iterdir()) if p.name not in ("summary.csv", "specs.jsonl")}


def run(args: argparse.Namespace) -> None:
    from distributed import Client, LocalCluster

    specs = random_specs(args.family, args.count, seed=args.seed, nodes=args.nodes)
    print(f"{args.count} x {args.family} (seed {args.seed}, about {args.nodes} nodes each) in "
          f"{args.rounds} round(s); {os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}")
    modes = [0, *args.workers]
    wall = dict.fromkeys(modes, 0.0)
    inside = dict.fromkeys(modes, 0.0)
    startup = dict.fromkeys(modes, 0.0)
    counts: dict[int, dict[str, int]] = {m: {} for m in modes}
    clusters = {}
    try:
        for workers in args.workers:  # started once; idle workers cost nothing
            start = time.perf_counter()
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=logging.ERROR)
            client = Client(cluster)
            client.wait_for_workers(workers)
            clusters[workers] = (cluster, client)
            startup[workers] = time.perf_counter() - start
        with tempfile.TemporaryDirectory(prefix="injmesh-bench-") as tmp:
            # Modes take turns on the same chunk of specs, round after round, so that a change
            # of load on a shared machine weighs on every mode alike.
            for r in range(args.rounds):
                chunk = specs[r * len(specs) // args.rounds:(r + 1) * len(specs) // args.rounds]
                for workers in modes:
                    out = Path(tmp) / f"w{workers}"
                    client = clusters[workers][1] if workers else None
                    start = time.perf_counter()
                    summary = (mesh_many(chunk, out, workers=0) if workers == 0
                               else mesh_many(chunk, out, client=client))
                    wall[workers] += time.perf_counter() - start
                    inside[workers] += sum(row.seconds or 0.0 for row in summary.rows)
                    for status, n in summary.counts.items():
                        counts[workers][status] = counts[workers].get(status, 0) + n
                print(f"  round {r + 1}: " + ", ".join(f"{m} worker(s) {wall[m]:.1f} s" for m in modes),
                      flush=True)
            hashes = {m: file_hashes(Path(tmp) / f"w{m}") for m in modes}
    finally:
        for cluster, client in reversed(clusters.values()):  # last in, first out: each cluster
            client.close()                                    # restores the log level it found
            cluster.close()

    serial = wall[0]
    print()
    print("| mode | meshes | wall s | meshes/s | speed-up | cluster start s | time inside tasks s |")
    print("|---|---|---|---|---|---|---|")
    for m in modes:
        mode = "serial (no Dask)" if m == 0 else f"LocalCluster, {m} worker(s)"
        done = ", ".join(f"{n} {s}" for s, n in counts[m].items())
        print(f"| {mode} | {done} | {wall[m]:.1f} | {args.count / wall[m]:.2f} | "
              f"{serial / wall[m]:.2f}x | {startup[m]:.1f} | {inside[m]:.1f} |")
    print()
    if 1 in wall:
        # Two views of what Dask costs per mesh on one worker: the extra wall time over meshing
        # in this process, and the wall time during which the worker was not inside a mesh task
        # (scheduling, shipping specs and files, writing them here).
        overhead = (wall[1] - serial) / args.count
        idle = (wall[1] - inside[1]) / args.count
        print(f"scheduling overhead per mesh: {overhead * 1000:.1f} ms (1 worker wall - serial "
              f"wall), {idle * 1000:.1f} ms (1 worker wall - time inside tasks)")
    same = all(h == hashes[0] for h in hashes.values())
    print(f"files identical across modes: {'yes' if same else 'NO'} ({len(hashes[0])} files)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--family", default="plates")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--nodes", type=int, default=200)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--rounds", type=int, default=10,
                        help="modes take turns on count/rounds specs at a time (default 10)")
    run(parser.parse_args())


if __name__ == "__main__":  # Dask starts workers by spawning: the guard is required
    main()
