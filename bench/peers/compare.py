#!/usr/bin/env python3
"""relit against a PyTorch implementation of the same "Ours" models, on the same machine in one session.

Runs `relit bench --suite e2e` (one training iteration of the fast and paper presets, one 128x128 frame),
bench/peers/torch_ours.py for both presets, and bench_mlp (the fused MLPs against a CLBlast GEMM chain and an
Eigen/OpenMP chain on the same batch), then writes OUT.json (every number) and OUT.md (the ratios).

    python3 bench/peers/compare.py --relit build/apps/relit --out peers     # PyTorch: apt-get install python3-torch
"""
import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--relit", default="build/apps/relit", help="the relit program")
    ap.add_argument("--python", default="/usr/bin/python3", help="a Python with torch (Debian: python3-torch)")
    ap.add_argument("--out", default="peers", help="writes OUT.json and OUT.md")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--bench-mlp", default="build/bench/bench_mlp", help="the bench_mlp program ('' to skip)")
    args = ap.parse_args()
    if subprocess.run([args.python, "-c", "import torch"], capture_output=True).returncode != 0:
        sys.exit("%s cannot import torch; install it (Debian: apt-get install python3-torch) or pass --python" %
                 args.python)
    relit_json = args.out + ".relit.json"
    subprocess.run([args.relit, "bench", "--suite", "e2e", "--repeats", str(args.repeats), "--json", relit_json],
                   check=True)
    relit = {r["name"]: r for r in json.load(open(relit_json))["devices"][0]["results"]}
    peers = {}
    for preset in ("fast", "paper"):
        path = "%s.torch_%s.json" % (args.out, preset)
        subprocess.run([args.python, os.path.join(HERE, "torch_ours.py"), "--preset", preset, "--steps",
                        str(args.repeats), "--json", path], check=True, stdout=subprocess.DEVNULL)
        peers[preset] = json.load(open(path))
    rows = []
    for preset in ("fast", "paper"):
        r = relit["train_step_" + preset]["median_s"]
        p = peers[preset]["train_step_s"]["median"]
        rows.append(("training iteration, `%s`" % preset, r, p, p / r))
    r = relit["relit_frame_fast"]["median_s"]
    p = peers["fast"]["frame_128_s"]
    rows.append(("128x128 frame, `fast`", r, p, p / r))
    lines = ["| | relit [s] | PyTorch %s [s] | speed-up |" % peers["fast"]["torch_version"], "|---|---:|---:|---:|"]
    lines += ["| %s | %.3f | %.3f | %.1fx |" % row for row in rows]
    doc = {"relit": relit, "pytorch": peers, "ratios": {row[0]: row[3] for row in rows}}
    if args.bench_mlp:
        mlp_json = args.out + ".bench_mlp.json"
        subprocess.run([args.bench_mlp, "--json", mlp_json], check=True, stdout=subprocess.DEVNULL)
        mlp = json.load(open(mlp_json))
        doc["bench_mlp"] = mlp
        lines += ["", "| fused MLP, batch 76,800 | vs CLBlast chain (forward / train) | vs Eigen chain (forward / train) |",
                  "|---|---:|---:|"]
        for net in mlp["nets"]:
            c, e = net.get("speedup_vs_clblast", {}), net.get("speedup_vs_eigen", {})
            lines.append("| %s | %.1fx / %.1fx | %.2fx / %.2fx |" % (net["name"], c.get("forward", float("nan")),
                                                                   c.get("train", float("nan")),
                                                                   e.get("forward", float("nan")),
                                                                   e.get("train", float("nan"))))
    with open(args.out + ".json", "w") as f:
        json.dump(doc, f, indent=2)
    with open(args.out + ".md", "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
