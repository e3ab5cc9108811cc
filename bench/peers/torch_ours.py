#!/usr/bin/env python3
"""The "Ours" model of relit written in plain PyTorch, as a user would, to time against relit on the same CPU.

It builds the networks of a relit preset (configs/fast.json or configs/paper.json: hash grids or NeRF frequency
encodings, SH encodings, MLPs with skips) and runs relit's training iteration on random rays through the unit
box: 1200 rays x 64 stratified samples, the property net (sigma, albedo, g, features), the light-conditioned SH
head scaled by the light's intensity, the visibility net, HG phase, direct light with the network's visibility,
the K = 64 direction indirect sum with the max(0, .) clamp, alpha compositing, L2 loss, backward, Adam; then the
visibility targets by a 64-step march through a cached density grid for a quarter of the rays, the visibility
loss, backward, Adam. It also renders one 128x128 frame (inference, 1024-ray tiles).

    python3 bench/peers/torch_ours.py --preset fast --json torch_fast.json
    python3 bench/peers/torch_ours.py --preset fast --compile --json torch_fast_compiled.json

--compile runs the renderer, the visibility net and the march through torch.compile (TorchInductor's C++/OpenMP
code on a CPU); the first iterations compile them, and that time is reported apart (compile_s), not timed.
Only the time is measured; the images are not compared (the random initialisations differ).
"""
import argparse
import json
import math
import os
import statistics
import time

import torch
import torch.nn.functional as F

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PRIMES = (1, 2654435761, 805459861)


class HashGrid(torch.nn.Module):
    """instant-ngp multiresolution hash encoding of [0, 1]^3 (trilinear interpolation of 8 corners per level)."""

    def __init__(self, n_levels, n_features_per_level, log2_hashmap_size, base_resolution, per_level_scale, **_):
        super().__init__()
        self.F = n_features_per_level
        self.levels = []
        sizes = []
        for level in range(n_levels):
            scale = base_resolution * per_level_scale ** level - 1.0
            res = int(math.ceil(scale)) + 1
            size = min(res ** 3, 2 ** log2_hashmap_size)
            self.levels.append((scale, res, size, res ** 3 > size))
            sizes.append(size)
        self.offsets = [0]
        for s in sizes:
            self.offsets.append(self.offsets[-1] + s)
        self.table = torch.nn.Parameter((torch.rand(self.offsets[-1], self.F) * 2 - 1) * 1e-4)
        self.n_output_dims = n_levels * self.F
        corners = torch.tensor([[(c >> d) & 1 for d in range(3)] for c in range(8)], dtype=torch.int64)
        self.register_buffer("corners", corners)

    def forward(self, x):
        outs = []
        for i, (scale, res, size, hashed) in enumerate(self.levels):
            p = x.clamp(0, 1) * scale + 0.5
            cell = p.floor()
            frac = p - cell
            v = cell.long().unsqueeze(1) + self.corners  # (n, 8, 3)
            if hashed:
                idx = (v[..., 0] * PRIMES[0]) ^ (v[..., 1] * PRIMES[1]) ^ (v[..., 2] * PRIMES[2])
                idx = idx & (size - 1)
            else:
                idx = v[..., 0] + v[..., 1] * res + v[..., 2] * res * res
            w = torch.where(self.corners.bool(), frac.unsqueeze(1), 1 - frac.unsqueeze(1)).prod(-1)  # (n, 8)
            feats = self.table[idx + self.offsets[i]]  # (n, 8, F)
            outs.append((w.unsqueeze(-1) * feats).sum(1))
        return torch.cat(outs, -1)


class Frequency(torch.nn.Module):
    def __init__(self, n_dims, n_frequencies, include_input=True, **_):
        super().__init__()
        self.n, self.include = n_frequencies, include_input
        self.n_output_dims = n_dims * (2 * n_frequencies + (1 if include_input else 0))
        self.register_buffer("freqs", (2.0 ** torch.arange(n_frequencies)) * math.pi)

    def forward(self, x):
        a = x.unsqueeze(-1) * self.freqs  # (n, d, L)
        parts = [torch.sin(a).flatten(1), torch.cos(a).flatten(1)]
        return torch.cat(([x] if self.include else []) + parts, -1)


def sh_basis(d, lmax):
    """Real spherical harmonics Y_lm(d) for l <= lmax, (n, (lmax+1)^2), by the associated Legendre recurrence."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    phi = torch.atan2(y, x)
    ct = z.clamp(-1, 1)
    st = torch.sqrt((1 - ct * ct).clamp_min(0))
    P = {(0, 0): torch.ones_like(ct)}
    for m in range(1, lmax + 1):
        P[(m, m)] = -(2 * m - 1) * st * P[(m - 1, m - 1)]
    for m in range(0, lmax):
        P[(m + 1, m)] = (2 * m + 1) * ct * P[(m, m)]
    for m in range(0, lmax + 1):
        for l in range(m + 2, lmax + 1):
            P[(l, m)] = ((2 * l - 1) * ct * P[(l - 1, m)] - (l + m - 1) * P[(l - 2, m)]) / (l - m)
    out = []
    for l in range(lmax + 1):
        for m in range(-l, l + 1):
            am = abs(m)
            k = math.sqrt((2 * l + 1) / (4 * math.pi) * math.factorial(l - am) / math.factorial(l + am))
            if m == 0:
                out.append(k * P[(l, 0)])
            elif m > 0:
                out.append(math.sqrt(2) * k * torch.cos(m * phi) * P[(l, am)])
            else:
                out.append(math.sqrt(2) * k * torch.sin(am * phi) * P[(l, am)])
    return torch.stack(out, -1)


class SHEncoding(torch.nn.Module):
    def __init__(self, degree, **_):
        super().__init__()
        self.lmax = degree - 1
        self.n_output_dims = degree * degree

    def forward(self, d):
        return sh_basis(d, self.lmax)


def encoding(cfg, n_dims):
    t = cfg.get("type", cfg.get("otype"))
    if t == "HashGrid":
        return HashGrid(**{k: v for k, v in cfg.items() if k != "type"})
    if t == "Frequency":
        return Frequency(n_dims, **{k: v for k, v in cfg.items() if k != "type"})
    if t == "SphericalHarmonics":
        return SHEncoding(**{k: v for k, v in cfg.items() if k != "type"})
    raise ValueError("encoding %s has no PyTorch peer" % t)


class MLP(torch.nn.Module):
    """ReLU MLP with skip connections re-injecting the network input (as relit's FullyFusedMLP)."""

    def __init__(self, n_in, n_out, n_neurons, n_hidden_layers, skip_layers=(), **_):
        super().__init__()
        self.skips = set(skip_layers)
        layers = []
        for l in range(n_hidden_layers + 1):
            fan_in = n_in if l == 0 else n_neurons + (n_in if l in self.skips else 0)
            layers.append(torch.nn.Linear(fan_in, n_neurons if l < n_hidden_layers else n_out))
        self.layers = torch.nn.ModuleList(layers)

    def forward(self, x):
        h = x
        for l, lin in enumerate(self.layers):
            if l in self.skips:
                h = torch.cat([h, x], -1)
            h = lin(h)
            if l < len(self.layers) - 1:
                h = F.relu(h)
        return h


class Ours(torch.nn.Module):
    def __init__(self, model):
        super().__init__()
        self.m = model
        r = model["renderer"]
        self.spr, self.K, self.lmax = r["n_samples"], r["n_dirs"], int(r["sh"])
        self.n_sh = (self.lmax + 1) ** 2
        self.nf = model["n_features"]
        p = model["property"]
        self.prop_enc = encoding(p["encoding"], 3)
        self.prop_net = MLP(self.prop_enc.n_output_dims, 5 + self.nf, **p["network"])
        i = model["indirect"]
        self.light_enc = encoding(i["light_encoding"], 3)
        self.sh_net = MLP(self.nf + self.light_enc.n_output_dims, 3 * self.n_sh, **i["network"])
        v = model["visibility"]
        self.vis_penc = encoding(v["position_encoding"], 3)
        self.vis_denc = encoding(v["direction_encoding"], 3)
        self.vis_net = MLP(self.vis_penc.n_output_dims + self.vis_denc.n_output_dims, 1, **v["network"])
        self.light_scale = model.get("light_position_scale", 0.125)
        self.i_ref = model.get("intensity_reference", 1000.0)

    def theta(self):
        return [*self.prop_enc.parameters(), *self.prop_net.parameters(), *self.sh_net.parameters()]

    def psi(self):
        return [*self.vis_penc.parameters(), *self.vis_net.parameters()]

    def properties(self, u):
        out = self.prop_net(self.prop_enc(u))
        return F.softplus(out[:, 0]), torch.sigmoid(out[:, 1:4]), 0.95 * torch.tanh(out[:, 4]), out[:, 5:]

    def visibility(self, u, w):
        return torch.sigmoid(self.vis_net(torch.cat([self.vis_penc(u), self.vis_denc(w)], -1)))[:, 0]

    def render(self, o, d, lp, li, dirs, basis):
        """Colours of rays (origin o, direction d) lit by point lights (position lp, RGB intensity li)."""
        n = o.shape[0]
        # Ray/box [-1, 1]^3 and stratified jittered samples.
        inv = 1.0 / d
        t0, t1 = (-1 - o) * inv, (1 - o) * inv
        tn = torch.minimum(t0, t1).amax(-1).clamp_min(0)
        tf = torch.maximum(t0, t1).amin(-1)
        tf = torch.maximum(tf, tn)
        s = (torch.arange(self.spr) + torch.rand(n, self.spr)) / self.spr
        t = tn[:, None] + (tf - tn)[:, None] * s
        delta = (tf - tn)[:, None].expand(-1, self.spr) / self.spr
        x = o[:, None] + t[..., None] * d[:, None]  # (n, S, 3)
        xf = x.reshape(-1, 3)
        u = xf * 0.5 + 0.5
        sigma, albedo, g, feat = self.properties(u)
        lpr = lp[:, None].expand(-1, self.spr, -1).reshape(-1, 3)
        to_l = lpr - xf
        r2 = (to_l * to_l).sum(-1)
        wl = to_l / r2.sqrt()[:, None]
        with torch.no_grad():  # gradient isolation: the render loss does not train the visibility net
            vis = self.visibility(u, wl)
        wo = -d[:, None].expand(-1, self.spr, -1).reshape(-1, 3)
        gg = g[:, None]

        def hg(mu):
            den = 1 + gg * gg - 2 * gg * mu
            return (1 - gg * gg) / (4 * math.pi * den * den.sqrt())

        lir = li[:, None].expand(-1, self.spr, -1).reshape(-1, 3)
        s_dir = hg((wo * wl).sum(-1, keepdim=True))[:, 0:1] * vis[:, None] * lir / r2[:, None]
        c = self.sh_net(torch.cat([feat, self.light_enc(lpr * self.light_scale)], -1)).view(-1, 3, self.n_sh)
        c = c * (lir / self.i_ref)[..., None]
        rad = torch.relu(torch.einsum("scj,kj->sck", c, basis))  # (N, 3, K)
        ph = hg(wo @ dirs.T)  # (N, K)
        s_ind = (4 * math.pi / self.K) * torch.einsum("sck,sk->sc", rad, ph)
        radiance = albedo * (s_dir + s_ind)
        alpha = 1 - torch.exp(-sigma.view(n, self.spr) * delta)
        trans = torch.cumprod(torch.cat([torch.ones(n, 1), 1 - alpha + 1e-10], -1), -1)[:, :-1]
        w = (trans * alpha)[..., None]
        return (w * radiance.view(n, self.spr, 3)).sum(1), x.detach(), wl.detach(), u.detach()


def march(grid, x, w, steps):
    """Transmittance from x along w to the box exit through a density grid (trilinear, midpoint steps)."""
    inv = 1.0 / w
    t0, t1 = (-1 - x) * inv, (1 - x) * inv
    tf = torch.maximum(t0, t1).amin(-1).clamp_min(0)
    dt = tf / steps
    depth = torch.zeros(x.shape[0])
    for i in range(steps):
        p = x + ((i + 0.5) * dt)[:, None] * w
        v = F.grid_sample(grid, p.view(1, -1, 1, 1, 3), align_corners=False).view(-1)
        depth = depth + v * dt
    return torch.exp(-depth)


def random_rays(n):
    d = F.normalize(torch.randn(n, 3), dim=-1)
    o = -3.5 * d + 0.3 * torch.randn(n, 3)
    lp = F.normalize(torch.randn(n, 3), dim=-1) * (3 + 2 * torch.rand(n, 1))
    li = torch.full((n, 3), 600.0)
    return o, d, lp, li


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="fast", choices=["fast", "paper"])
    ap.add_argument("--steps", type=int, default=5, help="timed training iterations (after one warm-up)")
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--json", default=None)
    ap.add_argument("--compile", action="store_true", help="torch.compile the forward passes (inductor)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    cfg = json.load(open(os.path.join(ROOT, "configs", args.preset + ".json")))
    model = Ours(cfg["model"])
    t = cfg["training"]
    opt = torch.optim.Adam(model.theta(), lr=t["optimizer"]["learning_rate"], betas=(0.9, 0.99), eps=1e-15)
    vopt = torch.optim.Adam(model.psi(), lr=t["visibility_optimizer"]["learning_rate"], betas=(0.9, 0.99), eps=1e-15)
    g = cfg["model"]["density_grid"]
    res, steps_march, frac = g["resolution"], g["march_steps"], g["visibility_fraction"]
    batch = t["batch_rays"]

    def refresh_grid():
        with torch.no_grad():
            c = (torch.arange(res) + 0.5) / res
            zz, yy, xx = torch.meshgrid(c, c, c, indexing="ij")
            u = torch.stack([xx, yy, zz], -1).view(-1, 3)
            sig = torch.cat([model.properties(u[i:i + 65536])[0] for i in range(0, u.shape[0], 65536)])
            return sig.view(1, 1, res, res, res)

    grid = refresh_grid()
    march_fn = march
    if args.compile:
        model.render = torch.compile(model.render)
        model.visibility = torch.compile(model.visibility)
        march_fn = torch.compile(march)

    def step():
        o, d, lp, li = random_rays(batch)
        dirs = F.normalize(torch.randn(model.K, 3), dim=-1)
        basis = sh_basis(dirs, model.lmax)
        color, x, wl, u = model.render(o, d, lp, li, dirs, basis)
        loss = ((color - torch.rand_like(color)) ** 2).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        m = int(batch * frac) * model.spr
        xs, ws, us = x.view(-1, 3)[:m], wl[:m], u[:m]
        target = march_fn(grid, xs, ws, steps_march)
        vloss = ((model.visibility(us, ws) - target) ** 2).mean()
        vopt.zero_grad(set_to_none=True)
        vloss.backward()
        vopt.step()

    t0 = time.perf_counter()
    step()  # warm-up; with --compile, two steps compile the forward and backward graphs
    if args.compile:
        step()
    compile_s = time.perf_counter() - t0
    times = []
    for _ in range(args.steps):
        t0 = time.perf_counter()
        step()
        times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    refresh_grid()
    refresh = time.perf_counter() - t0
    # One 128x128 frame, 1024-ray tiles, no gradients (compiled: a first frame compiles the no-grad graph).
    def render_frame():
        with torch.no_grad():
            t0 = time.perf_counter()
            o, d, lp, li = random_rays(128 * 128)
            dirs = F.normalize(torch.randn(model.K, 3), dim=-1)
            basis = sh_basis(dirs, model.lmax)
            for i in range(0, o.shape[0], 1024):
                model.render(o[i:i + 1024], d[i:i + 1024], lp[i:i + 1024], li[i:i + 1024], dirs, basis)
            return time.perf_counter() - t0

    if args.compile:
        render_frame()
    frame = render_frame()
    out = {"peer": "pytorch-compile" if args.compile else "pytorch", "torch_version": torch.__version__,
           "compiled": args.compile, "compile_s": compile_s, "threads": args.threads, "preset": args.preset,
           "batch_rays": batch, "train_step_s": {"median": statistics.median(times), "min": min(times),
                                                 "max": max(times), "repeats": len(times)},
           "grid_refresh_s": refresh, "frame_128_s": frame}
    print(json.dumps(out, indent=2))
    if args.json:
        tmp = args.json + ".tmp"
        with open(tmp, "w") as f:
            json.dump(out, f, indent=2)
        os.replace(tmp, args.json)


if __name__ == "__main__":
    main()
