#!/usr/bin/env python3
"""Runs every paper experiment at one scale: OUT/<experiment>/results.md for each, datasets in OUT/data.

    python bench/paper/run.py --scale ci --out results-ci
    python bench/paper/run.py --scale laptop --out results --only sh_ablation generalization
"""
import argparse
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
EXPERIMENTS = ["sh_ablation", "generalization", "comparison"]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scale", default="laptop", choices=["ci", "laptop", "laptop128", "gpu"])
    p.add_argument("--out", default="results")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--device", default=None)
    p.add_argument("--only", nargs="+", choices=EXPERIMENTS, default=EXPERIMENTS)
    args = p.parse_args()
    for name in args.only:
        cmd = [sys.executable, os.path.join(HERE, name + ".py"), "--scale", args.scale, "--out",
               os.path.join(args.out, name), "--seed", str(args.seed)]
        if args.device:
            cmd += ["--device", args.device]
        print("== " + name, flush=True)
        r = subprocess.run(cmd)
        if r.returncode != 0:
            sys.exit("experiment %s failed (exit %d)" % (name, r.returncode))


if __name__ == "__main__":
    main()
