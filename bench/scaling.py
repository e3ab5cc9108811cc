#!/usr/bin/env python3
"""Strong scaling over MPI ranks (docs/scaling.md): N ranks x 1 PoCL thread against 1 rank x 1 thread, side by side
in one run, for dataset generation and for the `fast` and `paper` training steps; the time of the gradient
reduction beside each step; then the expected step time on 8 and 64 GPUs from a model of compute and all-reduce.

    python bench/scaling.py --out results/scaling            # 2 ranks (this machine's cores)
    python bench/scaling.py --out results/scaling --ranks 4 --relit build/apps/relit

Each rank runs PoCL with one thread (POCL_MAX_PTHREAD_COUNT=1), pinned to its own core (mpirun --bind-to core), so
the ratio measures the parallel efficiency of relit's data parallelism, not PoCL's threading. Writes
OUT/scaling.json and OUT/scaling.md.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_btl_vader_single_copy_mechanism": "none", "POCL_MAX_PTHREAD_COUNT": "1", "RELIT_LOG": "warning"}


def relit(args, ranks, relit_exe, mpirun):
    """Runs relit ARGS on `ranks` ranks (1 thread each); returns (seconds, stdout)."""
    env = dict(os.environ, **MPI_ENV)
    cmd = [mpirun, "-np", str(ranks), "--bind-to", "core", "--map-by", "core",
           "-x", "POCL_MAX_PTHREAD_COUNT", "-x", "RELIT_LOG", relit_exe] + args
    start = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if p.returncode != 0:
        sys.exit(f"scaling: {' '.join(cmd)} failed ({p.returncode}):\n{p.stdout}\n{p.stderr}")
    return seconds, p.stdout


def profile(out):
    """The per-stage milliseconds `relit train --profile` prints: {stage: ms}."""
    stages = {}
    for line in out.splitlines():
        m = re.match(r"^  (.+?)\s+([0-9.]+) ms$", line)
        if m:
            stages[m.group(1).strip()] = float(m.group(2))
    return stages


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--relit", default=shutil.which("relit") or "build/apps/relit")
    ap.add_argument("--mpirun", default=shutil.which("mpirun") or "mpirun")
    ap.add_argument("--profile-steps", type=int, default=16,
                    help="steps averaged by relit train --profile (16: one density-grid refresh among them)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    n = args.ranks
    results = {"ranks": n, "cpu": cpu_model(), "generate": {}, "steps": {}}

    # Generation: the same dataset by 1 and by N ranks, timed; the files must be the same bytes.
    generate = ["generate", "--scene", "cloud", "--resolution", "64", "--train", "16", "--val", "2", "--test", "2",
                "--spp", "512", "--scene-resolution", "32", "--no-previews"]
    data = {}
    for ranks in (1, n):
        folder = out / f"data-{ranks}"
        if folder.exists():
            shutil.rmtree(folder)
        seconds, _ = relit(generate + ["--out", str(folder)], ranks, args.relit, args.mpirun)
        data[ranks] = folder
        results["generate"][str(ranks)] = seconds
        print(f"generate, {ranks} rank(s): {seconds:.1f} s", flush=True)
    same = all((data[1] / p.relative_to(data[n])).read_bytes() == p.read_bytes()
               for p in data[n].rglob("*") if p.is_file())
    results["generate"]["identical"] = same
    results["generate"]["speedup"] = results["generate"]["1"] / results["generate"][str(n)]

    # Training steps: relit train --profile (per-stage means over --profile-steps steps, after a warm-up step).
    for preset in ("fast", "paper"):
        results["steps"][preset] = {}
        for ranks in (1, n):
            _, text = relit(["train", str(data[1]), "--config", preset, "--out", str(out / f"run-{preset}-{ranks}"),
                             "--profile", str(args.profile_steps)], ranks, args.relit, args.mpirun)
            stages = profile(text)
            total = stages.pop("total")
            results["steps"][preset][str(ranks)] = {"step_ms": total, "stages": stages,
                                                    "reduction_ms": stages.get("gradient reduction (MPI)", 0.0)}
            print(f"{preset} step, {ranks} rank(s): {total:.1f} ms"
                  + (f" (reduction {stages.get('gradient reduction (MPI)', 0.0):.1f} ms)" if ranks > 1 else ""),
                  flush=True)
        one, many = results["steps"][preset]["1"], results["steps"][preset][str(n)]
        many["speedup"] = one["step_ms"] / many["step_ms"]
        many["reduction_share"] = many["reduction_ms"] / many["step_ms"]

    (out / "scaling.json").write_text(json.dumps(results, indent=2) + "\n")
    lines = [f"Strong scaling, {n} ranks x 1 thread against 1 rank x 1 thread ({results['cpu']}):", "",
             "| work | 1 rank | %d ranks | speed-up | gradient reduction |" % n, "|---|---|---|---|---|"]
    g = results["generate"]
    lines.append(f"| generate (20 views, 64², 512 spp) | {g['1']:.1f} s | {g[str(n)]:.1f} s | {g['speedup']:.2f}× | "
                 f"– (files identical: {'yes' if g['identical'] else 'NO'}) |")
    for preset in ("fast", "paper"):
        one, many = results["steps"][preset]["1"], results["steps"][preset][str(n)]
        lines.append(f"| `{preset}` training step | {one['step_ms']:.0f} ms | {many['step_ms']:.0f} ms | "
                     f"{many['speedup']:.2f}× | {many['reduction_ms']:.1f} ms ({100 * many['reduction_share']:.1f} %) |")
    (out / "scaling.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def cpu_model():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip() + f", {os.cpu_count()} cores"
    except OSError:
        pass
    return "unknown CPU"


if __name__ == "__main__":
    main()
