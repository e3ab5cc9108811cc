"""Shared machinery of the paper experiments (bench/paper/*.py): scales, datasets, runs, evaluation, tables.

Every step drives the `relit` command line through `python -m relit` (the same code as the `relit` program), so
an experiment prints the usual progress bars and leaves the usual folders behind:

    OUT/data/<dataset>/          relit generate            (skipped when complete)
    OUT/<experiment>/runs/<run>/ relit train               (resumed when its checkpoint is behind, skipped when done)
    OUT/<experiment>/runs/<run>/eval/metrics.json          relit eval (skipped when it matches the run's step)
    OUT/<experiment>/results.json, results.md, *.png       the tables and figures of the experiment

Everything is deterministic given the seeds, so rerunning an experiment reproduces its numbers; rerunning an
interrupted one continues where it stopped.
"""
import argparse
import copy
import json
import os
import subprocess
import sys
import time

# ---- scales -----------------------------------------------------------------------------------------------------

# A tiny model for the `ci` scale: the structure of `fast` (hash grids + fused MLPs), sized to train in seconds.
_CI_MODEL = {
    "renderer": {"n_samples": 16, "n_dirs": 16},
    "n_features": 4,
    "density_grid": {"resolution": 16, "march_steps": 16},
    "property": {
        "encoding": {"type": "HashGrid", "n_levels": 4, "n_features_per_level": 2, "log2_hashmap_size": 12,
                     "base_resolution": 4, "per_level_scale": 1.5},
        "network": {"type": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 1},
    },
    "indirect": {"network": {"type": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 1}},
    "environment": {"network": {"type": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 1}},
    "visibility": {
        "position_encoding": {"type": "HashGrid", "n_levels": 4, "n_features_per_level": 2, "log2_hashmap_size": 12,
                              "base_resolution": 4, "per_level_scale": 1.5},
        "direction_encoding": {"type": "SphericalHarmonics", "degree": 2},
        "network": {"type": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 1},
    },
}

# The `ci` scale's tiny model per method: each method's structure, at the size of _CI_MODEL; the baselines and
# Ours + BRDF train their direct light as their presets do (the marched shadow and its gradient, docs/baselines.md),
# and Bi et al. and Ours + BRDF render with the march as theirs do.
_CI_MLP = {"type": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 1}
# The model keys of the marched shadow and its gradient (the baselines' and Ours + BRDF's presets).
MARCHED_SHADOW = {"training_visibility": "march", "shadow_gradient": {"enabled": True}}
CI_MODELS = {
    "ours": _CI_MODEL,
    "ours_brdf": {**_CI_MODEL, **MARCHED_SHADOW, "inference_visibility": "march"},
    "bi": {"renderer": {"n_samples": 16, "n_fine_samples": 16},
           "density_grid": _CI_MODEL["density_grid"],
           "property": _CI_MODEL["property"],
           "coarse": _CI_MODEL["property"],
           "visibility": _CI_MODEL["visibility"], "inference_visibility": "march", **MARCHED_SHADOW},
    "nerv": {"renderer": {"n_samples": 16},
             "bounce": {"n_dirs": 4, "n_dirs_env": 2},
             "density_grid": _CI_MODEL["density_grid"],
             "property": _CI_MODEL["property"],
             "visibility": {"position_encoding": _CI_MODEL["visibility"]["position_encoding"],
                            "direction_encoding": _CI_MODEL["visibility"]["direction_encoding"],
                            "trunk": _CI_MLP, "network": _CI_MLP}, **MARCHED_SHADOW},
}

SCALES = {
    # End-to-end check of the scripts (CI): tiny images, views, networks and step counts. Numbers mean nothing.
    "ci": {"resolution": 16, "scene_resolution": 16, "train": 8, "val": 1, "test": 2, "spp": 4, "test_spp": 8,
           "generalization_views": 2, "steps": 30, "batch_rays": 256, "preset": None, "model": _CI_MODEL},
    # The numbers of docs/results.md: a 2-core CPU in about an hour per experiment.
    "laptop": {"resolution": 64, "scene_resolution": 64, "train": 60, "val": 4, "test": 20, "spp": 64, "test_spp": 256,
               "generalization_views": 10, "steps": 2000, "batch_rays": 1200, "preset": "fast", "model": {}},
    # The method comparison's protocol on a CPU (docs/results.md): the paper's image size, 3000 steps.
    "laptop128": {"resolution": 128, "scene_resolution": 64, "train": 100, "val": 4, "test": 20, "spp": 64,
                  "test_spp": 256, "generalization_views": 10, "steps": 3000, "batch_rays": 1200, "preset": "fast",
                  "model": {}},
    # The protocol of the paper (Zheng, Singh, Seidel, NeurIPS 2021) on a GPU: 128x128, 100 training views, the
    # paper-sized networks.
    "gpu": {"resolution": 128, "scene_resolution": 64, "train": 100, "val": 20, "test": 50, "spp": 64,
            "test_spp": 256, "generalization_views": 20, "steps": 30000, "batch_rays": 1200, "preset": "paper",
            "model": {}},
}


def parser(description, default_out, default_scale="laptop"):
    """The command line every experiment takes; an experiment adds its own arguments."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--scale", choices=sorted(SCALES), default=default_scale, help="sizes of data, networks and training")
    p.add_argument("--out", default=default_out, help="results folder (datasets go to OUT/../data)")
    p.add_argument("--seed", type=int, default=0, help="seeds datasets and training")
    p.add_argument("--device", default=None, help="OpenCL device selector (default: relit's choice)")
    p.add_argument("--steps", type=int, default=None, help="training steps per run (default: the scale's)")
    return p


def parse_args(description, default_out):
    """The command line of an experiment with no arguments of its own."""
    return parser(description, default_out).parse_args()


def learning_rate(lr):
    """The training overrides that set learning rate `lr` for both optimisers (render and visibility)."""
    return {"optimizer": {"learning_rate": lr}, "visibility_optimizer": {"learning_rate": lr}}


def merge(base, override):
    """`base` with the keys of `override` set recursively (dicts merge, everything else replaces)."""
    out = copy.deepcopy(base)
    for k, v in override.items():
        out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else copy.deepcopy(v)
    return out


# ---- running relit ------------------------------------------------------------------------------------------------

class Relit:
    """Runs `python -m relit` subcommands for an experiment, each step skipped when its result is already there."""

    def __init__(self, out, scale, seed=0, device=None, steps=None):
        self.out = os.path.abspath(out)
        self.scale_name = scale
        self.scale = SCALES[scale]
        self.seed = seed
        self.device = device
        self.steps = steps or self.scale["steps"]
        self.data_root = os.path.join(os.path.dirname(self.out), "data")
        os.makedirs(self.out, exist_ok=True)
        self.started = time.time()

    def cli(self, *args):
        cmd = [sys.executable, "-m", "relit"] + [str(a) for a in args]
        if self.device:
            cmd += ["--device", self.device]
        print("+ relit " + " ".join(str(a) for a in args), flush=True)
        r = subprocess.run(cmd)
        if r.returncode != 0:
            raise RuntimeError("relit %s failed (exit %d)" % (args[0], r.returncode))

    def dataset(self, name, scene="cloud", lighting="point", generalization=False, intensity=None,
                light_distance=None, max_bounces=None):
        """Generates OUT/../data/<name>-<scale> unless it is complete (its transforms_test.json exists). `scene` is
        a built-in name or a scene as a dict (written beside the dataset as <name>-<scale>.scene.json);
        `max_bounces` limits the path tracer's scattering events per path (1: single scattering)."""
        s = self.scale
        path = os.path.join(self.data_root, "%s-%s" % (name, self.scale_name))
        if os.path.exists(os.path.join(path, "transforms_test.json")):
            return path
        if isinstance(scene, dict):
            scene_path = path + ".scene.json"
            write_json(scene_path, scene)
            scene = scene_path
        args = ["generate", "--scene", scene, "--lighting", lighting, "--out", path, "--seed", self.seed,
                "--resolution", s["resolution"], "--scene-resolution", s["scene_resolution"], "--train", s["train"],
                "--val", s["val"], "--test", s["test"], "--spp", s["spp"], "--test-spp", s["test_spp"], "--overwrite"]
        if generalization:
            args += ["--generalization", "--generalization-views", s["generalization_views"]]
        if intensity is not None:
            args += ["--intensity"] + [str(v) for v in (intensity if isinstance(intensity, (list, tuple)) else [intensity])]
        if light_distance is not None:
            args += ["--light-distance", light_distance[0], light_distance[1]]
        if max_bounces is not None:
            args += ["--max-bounces", max_bounces]
        os.makedirs(self.data_root, exist_ok=True)
        self.cli(*args)
        return path

    def config(self, model=None, training=None, method="ours"):
        """A run config at this scale: the scale's preset (or tiny model) with `model`/`training` overrides."""
        s = self.scale
        if s["preset"]:
            import relit
            cfg = relit.preset(s["preset"] if method == "ours" else "%s-%s" % (method, s["preset"]))
        else:
            cfg = {"model": {}, "training": {}}
        cfg["method"] = method
        scale_model = CI_MODELS[method] if self.scale_name == "ci" else s["model"]
        cfg["model"] = merge(merge(cfg.get("model", {}), scale_model), model or {})
        t = {"batch_rays": s["batch_rays"], "steps": self.steps, "seed": self.seed,
             "validate_every": 0 if self.scale_name == "ci" else 500, "checkpoint_every": 500,
             "log_every": 10}  # the loss every 10 steps: convergence() smooths over enough of them
        cfg["training"] = merge(merge(cfg.get("training", {}), t), training or {})
        return cfg

    def train(self, name, dataset, config):
        """Trains OUT/runs/<name> to the configured steps: skipped when done, resumed when behind."""
        run = os.path.join(self.out, "runs", name)
        steps = config["training"]["steps"]
        done = last_logged_step(run)
        if done is not None and done >= steps and os.path.exists(os.path.join(run, "checkpoint.relit")):
            return run
        os.makedirs(os.path.dirname(run), exist_ok=True)
        if os.path.exists(os.path.join(run, "checkpoint.relit")):
            self.cli("train", dataset, "--out", run, "--steps", steps, "--resume")
        else:
            cfg_path = os.path.join(self.out, "runs", name + ".config.json")
            write_json(cfg_path, config)
            if os.path.exists(run):  # an attempt that stopped before its first checkpoint: start over
                import shutil
                shutil.rmtree(run)
            self.cli("train", dataset, "--config", cfg_path, "--out", run, "--steps", steps)
        return run

    def evaluate(self, run, dataset=None, splits=None):
        """relit eval into RUN/eval (skipped when its metrics.json is of the run's current step); the metrics."""
        out = os.path.join(run, "eval")
        metrics_path = os.path.join(out, "metrics.json")
        step = last_logged_step(run)
        if os.path.exists(metrics_path):
            m = read_json(metrics_path)
            if m.get("meta", {}).get("step") == step and (not splits or set(splits) <= set(m["splits"])):
                return m
        args = ["eval", run, "--out", out, "--no-images"]
        if dataset:
            args += ["--dataset", dataset]
        if splits:
            args += ["--split"] + list(splits)
        self.cli(*args)
        return read_json(metrics_path)

    def write_results(self, title, results, tables, notes=""):
        """OUT/results.json (every number) and OUT/results.md (the tables)."""
        results = dict(results)
        results["scale"] = self.scale_name
        results["settings"] = {k: v for k, v in self.scale.items() if k != "model"}
        results["settings"]["steps"] = self.steps
        results["seed"] = self.seed
        results["elapsed_seconds"] = round(time.time() - self.started, 1)
        write_json(os.path.join(self.out, "results.json"), results)
        lines = ["# " + title, "",
                 "Scale `%s` (%dx%d, %d training views, %d steps); seed %d. Every number is in results.json." % (
                     self.scale_name, self.scale["resolution"], self.scale["resolution"], self.scale["train"],
                     self.steps, self.seed), ""]
        for t in tables:
            lines += t + [""]
        if notes:
            lines += [notes, ""]
        write_text(os.path.join(self.out, "results.md"), "\n".join(lines))
        print("results written to " + os.path.join(self.out, "results.md"), flush=True)


# ---- files and tables ---------------------------------------------------------------------------------------------

def last_logged_step(run):
    """The step of the last line of RUN/log.jsonl, or None."""
    log = os.path.join(run, "log.jsonl")
    if not os.path.exists(log):
        return None
    step = None
    with open(log) as f:
        for line in f:
            line = line.strip()
            if line:
                step = json.loads(line)["step"]
    return step


def training_seconds(run):
    """Training time of RUN summed over its relit train calls (each call's log restarts its clock)."""
    log = os.path.join(run, "log.jsonl")
    if not os.path.exists(log):
        return None
    total, last = 0.0, 0.0
    with open(log) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            e = json.loads(line).get("elapsed", 0.0)
            if e < last:  # a new call
                total += last
            last = e
    return total + last


def read_json(path):
    with open(path) as f:
        return json.load(f)


def write_text(path, text):
    """Writes through a temporary file and a rename: an existing file is never left half-written."""
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def write_json(path, value):
    write_text(path, json.dumps(value, indent=2) + "\n")


def markdown_table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" if i == 0 else "---:" for i in range(len(header))) + "|"]
    for r in rows:
        out.append("| " + " | ".join(fmt(v) for v in r) + " |")
    return out


def fmt(v):
    """A table cell: floats to 4 decimals below 1.5 and 2 above, a missing value (None) as a dash."""
    if v is None:
        return "–"
    if isinstance(v, float):
        return "%.4f" % v if abs(v) < 1.5 else "%.2f" % v
    return str(v)


def fmt_sci(v):
    """A small positive number in three significant digits (a loss: 2.41e-03), a missing one as a dash."""
    return "–" if v is None else "%.3g" % v


def split_means(metrics, split):
    """PSNR and SSIM of a split over the whole image (the paper's protocol)."""
    s = metrics["splits"][split]
    return s["psnr"], s["ssim"]


def object_means(metrics, split):
    """The object's protocol of a split (docs/evaluation.md): a dict of psnr, ssim, rel_mse, flip, clipped (None
    where missing)."""
    o = metrics["splits"][split].get("object", {})
    return {k: o.get(k) for k in ("psnr", "ssim", "rel_mse", "flip", "clipped")}


def logged_losses(run):
    """[(step, render loss)] of RUN/log.jsonl."""
    out = []
    with open(os.path.join(run, "log.jsonl")) as f:
        for line in f:
            line = line.strip()
            if line:
                e = json.loads(line)
                out.append((e["step"], e["loss"]))
    return out


def convergence(run, early=200):
    """Did the run's loss keep falling? The smoothed loss over the last 10 % of the steps against the smoothed
    loss around step `early` (the mean of the logged losses in [early - 50, early + 50]); `converged` when the end
    is at most half of it (the target: the loss keeps falling), `rising` when the end is above it (a runaway); None
    when the run is too short to tell (under 2 x early). Between the two the loss fell, but by less than half."""
    losses = logged_losses(run)
    if not losses or losses[-1][0] < 2 * early:
        return {"early": None, "last": None, "ratio": None, "converged": None, "rising": None}
    last_step = losses[-1][0]
    near = [l for s, l in losses if abs(s - early) <= 50]
    tail = [l for s, l in losses if s > 0.9 * last_step]
    e, t = sum(near) / len(near), sum(tail) / len(tail)
    return {"early": e, "last": t, "ratio": t / e if e > 0 else None, "converged": bool(t <= 0.5 * e),
            "rising": bool(t > e)}


# One colour per method in every figure.
METHOD_COLORS = {"Bi et al.": "tab:blue", "NeRV": "tab:orange", "Ours": "tab:green", "Ours + BRDF": "tab:red"}


def _figure(size=(5, 3.4)):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=size, dpi=120)
    return plt, fig, ax


def _save(plt, fig, ax, path, title, xlabel, ylabel, legend):
    """Titles, grid and legend, then the figure written to a temporary name and renamed onto `path`."""
    ax.set_title(title)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    if legend:
        ax.legend(fontsize="small")
    fig.tight_layout()
    tmp = path + ".tmp.png"
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)


def plot(path, title, xlabel, series, xticks=None, ylabel="PSNR [dB]"):
    """A line plot of {label: (xs, ys)} (matplotlib, no display needed)."""
    plt, fig, ax = _figure()
    for label, (xs, ys) in series.items():
        ax.plot(xs, ys, marker="o", label=label)
    if xticks is not None:
        ax.set_xticks(range(len(xticks)) if isinstance(xticks[0], str) else xticks)
        if isinstance(xticks[0], str):
            ax.set_xticklabels(xticks)
    _save(plt, fig, ax, path, title, xlabel, ylabel, len(series) > 1)


def plot_lines(path, title, xlabel, ylabel, lines, logy=False):
    """Curves [(label, xs, ys, matplotlib style)] without markers; xs None draws a horizontal line at ys."""
    plt, fig, ax = _figure((6.4, 4.2))
    for label, xs, ys, style in lines:
        if xs is None:
            ax.axhline(ys, label=label, linewidth=1, **style)
        else:
            ax.plot(xs, ys, label=label, linewidth=1, **style)
    if logy:
        ax.set_yscale("log")
    _save(plt, fig, ax, path, title, xlabel, ylabel, len(lines) > 1)
