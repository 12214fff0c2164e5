"""Throughput of batch meshing: serial, then Dask LocalClusters of 1, 2, ... worker processes.

    python benchmarks/batch_throughput.py                  # 1000 plates of about 200 nodes
    python benchmarks/batch_throughput.py --count 100 --workers 1 2

Every mode meshes the same specs (``random_specs("plates", count, seed=0, nodes=200)``: paper-size
meshes, 95-309 nodes in the paper's Section 5) into its own directory; the table gives meshes per
second, the speed-up over serial and the scheduling overhead per mesh (wall time on one worker
minus wall time in this process, and wall time on one worker minus the time spent inside the
mesh tasks, each divided by the number of meshes: what going through Dask costs).  Cluster
start-up is timed separately and left out of the throughput.  The files of every mode are
compared at the end: they must be identical, bit for bit.
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
    specs = random_specs(args.family, args.count, seed=args.seed, nodes=args.nodes)
    print(f"{args.count} x {args.family} (seed {args.seed}, about {args.nodes} nodes each); "
          f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}")
    rows = []
    hashes = {}
    with tempfile.TemporaryDirectory(prefix="injmesh-bench-") as tmp:
        serial_wall = None
        for workers in [0, *args.workers]:
            out = Path(tmp) / f"w{workers}"
            if workers == 0:
                start = time.perf_counter()
                summary = mesh_many(specs, out, workers=0)
                wall, startup = time.perf_counter() - start, 0.0
                serial_wall = wall
            else:
                from distributed import Client, LocalCluster

                start = time.perf_counter()
                with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=logging.ERROR) as cluster, \
                        Client(cluster) as client:
                    client.wait_for_workers(workers)
                    startup = time.perf_counter() - start
                    start = time.perf_counter()
                    summary = mesh_many(specs, out, client=client)
                    wall = time.perf_counter() - start
            task_seconds = sum(r.seconds or 0.0 for r in summary.rows)
            rows.append((workers, summary, wall, startup, task_seconds))
            hashes[workers] = file_hashes(out)
            print(f"  {'serial' if workers == 0 else f'{workers} worker(s)'}: {wall:.1f} s "
                  f"{summary.counts}", flush=True)

    assert serial_wall is not None
    one = next((r for r in rows if r[0] == 1), None)
    # Two views of what Dask costs per mesh on one worker: the extra wall time over meshing in
    # this process, and the wall time during which the worker was not inside a mesh task
    # (scheduling, shipping specs and files, writing them here).
    overhead = (one[2] - serial_wall) / args.count if one else float("nan")
    idle = (one[2] - one[4]) / args.count if one else float("nan")
    print()
    print("| mode | meshes | wall s | meshes/s | speed-up | cluster start s | sum of task s |")
    print("|---|---|---|---|---|---|---|")
    for workers, summary, wall, startup, task_seconds in rows:
        mode = "serial (no Dask)" if workers == 0 else f"LocalCluster, {workers} worker(s)"
        ok = summary.counts.get("ok", 0)
        print(f"| {mode} | {ok}/{len(summary.rows)} | {wall:.1f} | {args.count / wall:.2f} | "
              f"{serial_wall / wall:.2f}x | {startup:.1f} | {task_seconds:.1f} |")
    print()
    print(f"scheduling overhead per mesh: {overhead * 1000:.1f} ms (1 worker wall - serial wall), "
          f"{idle * 1000:.1f} ms (1 worker wall - time inside tasks)")
    reference = hashes[0]
    same = all(h == reference for h in hashes.values())
    print(f"files identical across modes: {'yes' if same else 'NO'} ({len(reference)} files)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--family", default="plates")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--nodes", type=int, default=200)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    run(parser.parse_args())


if __name__ == "__main__":  # Dask starts workers by spawning: the guard is required
    main()
