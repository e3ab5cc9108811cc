#!/usr/bin/env python3
"""relit against a PyTorch implementation of the same "Ours" models, on the same machine in one session.

Runs `relit bench --suite e2e` (one training iteration of the fast and paper presets, one 128x128 frame),
bench/peers/torch_ours.py for both presets, eager and with torch.compile, and bench_mlp (the fused MLPs against a CLBlast GEMM chain and an
Eigen/OpenMP chain on the same batch), then writes OUT.json (every number) and OUT.md (the ratios).

    scripts/setup.sh --peers                      # PyTorch 2.x from PyPI into .venv-peers
    python3 bench/peers/compare.py --relit build/apps/relit --out peers
"""
import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def write_atomic(path, text):
    """Writes `text` to a temporary file beside `path`, flushed to disk, then renames it over `path`."""
    tmp = "%s.tmp%d" % (path, os.getpid())
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--relit", default="build/apps/relit", help="the relit program")
    ap.add_argument("--python", default=os.path.join(ROOT, ".venv-peers", "bin", "python"),
                    help="a Python with torch 2.x (scripts/setup.sh --peers makes .venv-peers)")
    ap.add_argument("--no-compile", action="store_true", help="skip the torch.compile peer")
    ap.add_argument("--out", default="peers", help="writes OUT.json and OUT.md")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--bench-mlp", default="build/bench/bench_mlp", help="the bench_mlp program ('' to skip)")
    args = ap.parse_args()
    if subprocess.run([args.python, "-c", "import torch"], capture_output=True).returncode != 0:
        sys.exit("%s cannot import torch; run scripts/setup.sh --peers or pass --python" % args.python)
    relit_json = args.out + ".relit.json"
    subprocess.run([args.relit, "bench", "--suite", "e2e", "--repeats", str(args.repeats), "--json", relit_json],
                   check=True)
    relit = {r["name"]: r for r in json.load(open(relit_json))["devices"][0]["results"]}
    modes = ["eager"] + ([] if args.no_compile else ["compile"])
    peers = {mode: {} for mode in modes}
    for mode in modes:
        for preset in ("fast", "paper"):
            path = "%s.torch_%s_%s.json" % (args.out, mode, preset)
            cmd = [args.python, os.path.join(HERE, "torch_ours.py"), "--preset", preset, "--steps", str(args.repeats),
                   "--json", path] + (["--compile"] if mode == "compile" else [])
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            peers[mode][preset] = json.load(open(path))
    rows = []
    for preset in ("fast", "paper"):
        r = relit["train_step_" + preset]["median_s"]
        rows.append(["training iteration, `%s`" % preset, r] +
                    [peers[m][preset]["train_step_s"]["median"] for m in modes])
    r = relit["relit_frame_fast"]["median_s"]
    rows.append(["128x128 frame, `fast`", r] + [peers[m]["fast"]["frame_128_s"] for m in modes])
    version = peers["eager"]["fast"]["torch_version"]
    head = "| | relit [s] | PyTorch %s eager [s] | speed-up |" % version
    rule = "|---|---:|---:|---:|"
    if "compile" in modes:
        head += " torch.compile [s] | speed-up |"
        rule += "---:|---:|"
    lines = [head, rule]
    for row in rows:
        cells = ["%.3f | %.1fx" % (p, p / row[1]) for p in row[2:]]
        lines.append("| %s | %.3f | %s |" % (row[0], row[1], " | ".join(cells)))
    compile_s = {m: {p: peers[m][p]["compile_s"] for p in peers[m]} for m in modes}
    doc = {"relit": relit, "pytorch": peers, "compile_s": compile_s,
           "ratios": {row[0]: {m: row[2 + i] / row[1] for i, m in enumerate(modes)} for row in rows}}
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
    write_atomic(args.out + ".json", json.dumps(doc, indent=2) + "\n")
    write_atomic(args.out + ".md", "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
