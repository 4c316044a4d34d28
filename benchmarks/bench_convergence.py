#!/usr/bin/env python3
"""Benchmark: convergence of the ray-traced received power of the serving BS -> UE links.

Traces a reproducible subset of the serving links of a config (every ``--every``-th trajectory
point, its three serving links) at a ladder of settings (tracing direction, maximum depth, rays
per source, Sionna's candidate generator) and compares each with a reference, per link:

* seconds per link, timed in this run (each setting in a fresh process, its kernels compiled by
  an untimed warm-up trace of the first point's links; no propagation cache);
* received power (sum of |a|^2 over the valid paths) against the reference's, dB: median, p10,
  p90 of the signed deviation, p90 of |deviation| and the share of links more than 3 dB off
  (a link that lost or gained all its paths counts as infinitely off);
* the share of links whose strongest reference path is found (same interaction sequence, delay
  within SAME_PATH_TOL_S of veriloc_rt.propagation.link_metrics: distinct paths of one sequence
  come within a nanosecond of each other, so a looser window would take one for another);
* first path: delay deviation (m), and its power relative to the link's strongest path (dB);
* paths per link.

The reference is one of the settings or ``union`` (default): every distinct path that any
setting of the config's tracing direction found. Sionna RT refines each candidate to the exact
path with the image method, so a found path is exact and a trace can only miss paths: the union
is the best lower bound on the converged channel the run gives, and the row "reference without
<costliest setting>" shows how much that setting still adds to it. The tracing directions are
kept apart because Sionna RT's own diffraction coefficient gives one path different powers in
the two directions (measured on the "path identity" lines). Rows ``A+B`` are unions of settings
(cost: the sum): of the two tracing directions, or of one setting with other PathSolver seeds.
A second table splits the reference power by path class (interaction sequence in BS -> UE
order) and shows how much of each class some settings find.

Everything comes from the config (``--set path=value`` patches it, e.g. the diffraction
coefficient), so the study re-runs on any scene or physics. The 1e7-ray settings take minutes
per handful of links: run the full study in the background, e.g.

    nohup .venv/bin/python benchmarks/bench_convergence.py --keep out/conv-keep \\
        --out out/conv > out/conv.txt 2>&1 &

and after a physics change, e.g. ``--set propagation.raytrace.diffraction_coefficient='"utd"'``.

``--keep DIR`` saves each setting's traced paths (and timing) and reuses them on the next run
with the same config, links and setting (the reused timing is the one measured then).
``--quick``: 4 points, a short ladder (a smoke test of the script, under a minute). The
figures of the default run are in docs/convergence.md.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import harness
import numpy as np

SPEED_OF_LIGHT = 299_792_458.0
#: default ladder: direction:max_depth:rays_per_source[:nd][:s<seed>] (nd: Sionna's
#: non-deterministic candidate generator, PathSolver(deterministic=False); s<seed>: the
#: PathSolver seed, which draws the diffraction events, instead of the config's)
DEFAULT_SETTINGS = (
    "reciprocal:4:5e4", "reciprocal:4:2e5", "reciprocal:4:1e6", "reciprocal:4:2e6",
    "reciprocal:4:5e6", "reciprocal:4:1e7",
    "reciprocal:3:5e4", "reciprocal:3:1e6", "reciprocal:3:2e6",
    "reciprocal:5:5e4", "reciprocal:5:2e5", "reciprocal:5:1e6",
    "reciprocal:6:5e4", "reciprocal:6:2e5", "reciprocal:6:1e6", "reciprocal:6:2e6",
    "forward:4:5e4", "forward:4:2e5", "forward:4:1e6", "forward:4:2e6",
    "forward:6:1e6",
    "reciprocal:4:1e6:nd",
    "reciprocal:4:5e4:s2", "reciprocal:4:5e4:s3", "reciprocal:4:5e4:s4",
)
DEFAULT_UNIONS = ("reciprocal:4:5e4+forward:4:5e4", "reciprocal:4:2e5+forward:4:2e5",
                  "reciprocal:4:1e6+forward:4:1e6",
                  "reciprocal:4:5e4+reciprocal:4:5e4:s2+reciprocal:4:5e4:s3+reciprocal:4:5e4:s4")
QUICK_SETTINGS = ("reciprocal:4:5e4", "reciprocal:4:2e5", "forward:4:5e4", "reciprocal:5:5e4")
QUICK_UNIONS = ("reciprocal:4:5e4+forward:4:5e4",)
#: rows of the path-class table
CLASS_SETTINGS = ("reciprocal:4:5e4", "reciprocal:4:1e6", "reciprocal:4:1e7", "forward:4:1e6",
                  "reciprocal:6:1e6")
#: a link is "off" when its power is more than this from the reference's (the issue's p90 target:
#: share off <= 10 % is p90 |dev| <= 3 dB)
POWER_TOL_DB = 3.0
#: a first path within this of the reference's is the same (1 m = 3.3 ns)
FIRST_PATH_TOL_M = 1.0


def parse_setting(spec: str) -> dict:
    """direction:depth:rays[:nd][:s<seed>][:ex|:bo|:sa] -> setting dict (seed None: the
    config's; ':ex' / ':bo' / ':sa' set propagation.raytrace.edge_candidates to 'exhaustive' /
    'both' / 'sampled', none: the config's)."""
    parts = spec.split(":")
    extra = parts[3:]
    ok = len(parts) >= 3 and parts[0] in ("reciprocal", "forward") and \
        all(e in ("nd", "det", "ex", "bo", "sa") or (e[:1] == "s" and e[1:].isdigit()) for e in extra)
    if not ok:
        raise SystemExit(f"error: setting {spec!r}: expected "
                         "direction:depth:rays[:nd][:s<seed>][:ex|:bo|:sa], "
                         "direction 'reciprocal' or 'forward'")
    seed = next((int(e[1:]) for e in extra if e[:1] == "s" and e[1:].isdigit()), None)
    edge = {"ex": "exhaustive", "bo": "both", "sa": "sampled"}
    edge = next((edge[e] for e in extra if e in edge), None)
    return {"direction": parts[0], "max_depth": int(parts[1]),
            "rays_per_source": int(float(parts[2])), "deterministic": "nd" not in extra,
            "seed": seed, "edge_candidates": edge}


def label(s: dict) -> str:
    return (f"{s['direction'][:3]} d{s['max_depth']} {s['rays_per_source']:.0e}"
            + ("" if s["deterministic"] else " nd")
            + ("" if s.get("seed") is None else f" s{s['seed']}")
            + ("" if s.get("edge_candidates") is None else f" {s['edge_candidates'][:2]}"))


def patched(data: dict, patch: dict) -> dict:
    from veriloc_rt.config import patch_data
    from veriloc_rt.errors import InputError

    try:
        return patch_data(data, patch, must_exist=True)
    except InputError as exc:
        raise SystemExit(f"error: {exc}") from None


# -- tracing (child process) -----------------------------------------------------------------
def child(job: Path, out: Path) -> None:
    """Trace the job's links with its setting in this process; save paths and timing."""
    from veriloc_rt.config import config_from_dict

    spec = json.loads(job.with_suffix(".json").read_text())
    with np.load(job) as d:
        tx, rx, first = d["tx"], d["rx"], int(d["first_point_links"])
    s = spec["setting"]
    cfg = config_from_dict(patched(spec["config"], {
        "propagation.raytrace.direction": s["direction"],
        "propagation.raytrace.max_depth": s["max_depth"],
        "propagation.raytrace.rays_per_source": s["rays_per_source"]}
        | ({} if s.get("edge_candidates") is None else
           {"propagation.raytrace.edge_candidates": s["edge_candidates"]})))
    seed = cfg.seed if s.get("seed") is None else s["seed"]
    tracer = harness.loaded_tracer(spec["scene_xml"], cfg, seed)
    st = tracer.sionna_tracer()
    if not s["deterministic"]:
        from veriloc_rt.backend import import_sionna
        st.solver = import_sionna().PathSolver(deterministic=False)
    load0 = os.getloadavg()[0]
    _, warm = harness.timed_links(tracer, tx[:first], rx[:first])   # compile kernels
    calls0 = tracer.stats["calls"]
    raw, dt = harness.timed_links(tracer, tx, rx)
    np.savez(out, tau=raw.tau, a=raw.a, valid=raw.valid, interactions=raw.interactions,
             seconds=dt, warmup_s=warm, calls=tracer.stats["calls"] - calls0,
             load_start=load0, load_end=os.getloadavg()[0],
             maxrss_gib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20)


# -- study (parent) --------------------------------------------------------------------------
def build_links(cfg_data: dict, work: Path, every: int, max_points: int | None):
    from veriloc_rt.config import config_from_dict

    with harness.geometry(config_from_dict(cfg_data), work / "scene") as geo:
        pts = np.arange(0, geo.num_points, every)
        if max_points:
            pts = pts[:max_points]
        return (geo, pts, *harness.serving_links(geo, pts))


def trace_setting(setting: dict, cfg_data: dict, scene_xml: Path, tx, rx, work: Path,
                  keep: Path | None, digest: str) -> dict:
    name = label(setting).replace(" ", "_")
    kept = keep / f"{digest}_{name}.npz" if keep else None
    if kept and kept.is_file():
        print(f"# {label(setting)}: reusing {kept}", flush=True)
    else:
        job = work / f"job_{name}.npz"
        np.savez(job, tx=tx, rx=rx, first_point_links=3)
        job.with_suffix(".json").write_text(json.dumps(
            {"config": cfg_data, "setting": setting, "scene_xml": str(scene_xml)}))
        out = kept or work / f"{name}.npz"
        if kept:
            kept.parent.mkdir(parents=True, exist_ok=True)
        t = time.perf_counter()
        subprocess.run([sys.executable, __file__, "--child", str(job), str(out)], check=True)
        print(f"# {label(setting)}: traced in {time.perf_counter() - t:.0f} s", flush=True)
        kept = out
    with np.load(kept) as d:
        r = {k: d[k] for k in d.files}
    if r["a"].ndim == 4:    # polarimetric [link, path, rx port, tx port]: the config's ports
        from veriloc_rt.config import config_from_dict
        from veriloc_rt.propagation.polarization import project

        pol = config_from_dict(cfg_data).propagation.raytrace.polarization
        r["a"] = project(r["a"], pol.ue, pol.bs)
        r["valid"] = r["valid"] & (r["a"] != 0)
    r["power"] = np.abs(r["a"]) ** 2
    return r


def arrays(r: dict) -> tuple:
    return r["tau"], r["power"], r["interactions"], r["valid"]


def row_metrics(test: tuple, ref: tuple, lm) -> dict:
    dev = lm.link_deviation(test, ref)
    p = dev["power_dev_db"]
    q = lm.quantile
    off = np.abs(p) > POWER_TOL_DB
    fd = np.abs(dev["first_delay_dev_s"]) * SPEED_OF_LIGHT
    has, has_r = test[3].any(-1), ref[3].any(-1)
    first_off = (has != has_r) | (has & has_r & ~(fd <= FIRST_PATH_TOL_M))
    rel_dev = np.abs(dev["first_rel_db"] - dev["first_rel_db_ref"])
    return {"power_dev_db_p10": q(p, 10), "power_dev_db_p50": q(p, 50), "power_dev_db_p90": q(p, 90),
            "power_absdev_db_p90": q(np.abs(p), 90), "power_off_pct": 100 * float(off.mean()),
            "strongest_found_pct": 100 * float(np.nanmean(dev["strongest_found"])),
            "first_path_dev_m_p50": q(fd, 50), "first_path_dev_m_p90": q(fd, 90),
            "first_path_off_pct": 100 * float(first_off.mean()),
            "first_rel_db_p50": q(dev["first_rel_db"], 50),
            "first_rel_absdev_db_p90": q(rel_dev, 90),
            "paths_per_link_p50": q(test[3].sum(-1), 50),
            "links_with_path_pct": 100 * float(has.mean())}


def _f(v, nd=2) -> str:
    if v is None:
        return "n/a"
    if isinstance(v, float) and np.isinf(v):
        return "-inf" if v < 0 else "inf"
    return f"{v:.{nd}f}"


COLUMNS = (("setting", lambda r: r["label"]), ("s/link", lambda r: _f(r.get("s_per_link"), 3)),
           ("power dev p10/p50/p90 dB", lambda r: "/".join(_f(r[k], 1) for k in (
               "power_dev_db_p10", "power_dev_db_p50", "power_dev_db_p90"))),
           ("|dev| p90 dB", lambda r: _f(r["power_absdev_db_p90"], 1)),
           ("> 3 dB off %", lambda r: _f(r["power_off_pct"], 0)),
           ("strongest found %", lambda r: _f(r["strongest_found_pct"], 0)),
           ("first path dev p50/p90 m", lambda r: f"{_f(r['first_path_dev_m_p50'])}/"
                                                  f"{_f(r['first_path_dev_m_p90'])}"),
           ("first path > 1 m off %", lambda r: _f(r["first_path_off_pct"], 0)),
           ("first/strongest p50 dB", lambda r: _f(r["first_rel_db_p50"], 1)),
           ("paths/link p50", lambda r: _f(r["paths_per_link_p50"], 0)))


def markdown(rows: list[dict]) -> str:
    lines = ["| " + " | ".join(h for h, _ in COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    lines += ["| " + " | ".join(f(r) for _, f in COLUMNS) + " |" for r in rows]
    return "\n".join(lines)


def class_table(ref: tuple, traces: dict, names: list[str], lm, top: int = 8) -> tuple[str, list]:
    """Reference power by path class, and the share of each class's power each setting finds.

    Each link counts equally: a path weighs its share of its link's reference power, a class's
    share is the mean over the links of its paths' weights, and a setting finds the weight of
    the class's paths it has."""
    tau, power, inter, valid = ref
    classes = np.array([[lm.path_class(inter[i, j]) for j in range(tau.shape[1])]
                        for i in range(tau.shape[0])])
    p_link = lm.link_power(power, valid)
    w = np.where(valid, power, 0) / np.where(p_link > 0, p_link, 1.0)[:, None]
    n_links = int((p_link > 0).sum())
    by = {c: float(w[valid & (classes == c)].sum()) for c in np.unique(classes[valid])}
    order = sorted(by, key=by.get, reverse=True)
    found = {}
    for n in names:
        t = traces[n]
        hit = np.zeros(valid.shape, bool)
        for j in range(tau.shape[1]):
            hit[:, j] = lm.has_path(t[0], t[2], t[3], np.where(valid[:, j], tau[:, j], np.nan),
                                    inter[:, j])
        found[n] = {c: 100 * float(w[valid & hit & (classes == c)].sum()) / by[c] for c in by}
        found[n]["all"] = 100 * float(w[valid & hit].sum()) / max(n_links, 1)
    head = ["class (BS -> UE)", "share of link power % (mean)", "links with it"] + \
           [f"found by {n} %" for n in names]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    out = []
    for c in order[:top] + ["all"]:
        share = 100 * (by[c] if c != "all" else n_links) / max(n_links, 1)
        nl = int((valid & (classes == c)).any(-1).sum()) if c != "all" else n_links
        cells = [c, f"{share:.1f}", str(nl)] + [f"{found[n][c]:.0f}" for n in names]
        lines.append("| " + " | ".join(cells) + " |")
        out.append({"class": c, "share_pct": share, "links": nl,
                    "found_pct": {n: found[n][c] for n in names}})
    return "\n".join(lines), out


def _copies(a: tuple, b: tuple, lm):
    """Copies of one path in two traces of the same links, one row per pair: delay difference
    (s), power ratio (dB), the path's power relative to its link's strongest path in ``a`` (dB),
    its number of interactions, whether it has a diffraction."""
    depth = max(a[2].shape[-1], b[2].shape[-1])
    ia, ib = lm.pad_depth(a[2], depth), lm.pad_depth(b[2], depth)
    p_max = np.where(a[3], a[1], 0).max(axis=-1)
    out = []
    for link in range(a[0].shape[0]):
        for j in np.flatnonzero(a[3][link]):
            same = b[3][link] & np.all(ib[link] == ia[link, j], axis=-1) & \
                (np.abs(b[0][link] - a[0][link, j]) <= lm.SAME_PATH_TOL_S)
            for k in np.flatnonzero(same):
                out.append((b[0][link, k] - a[0][link, j],
                            10 * np.log10(b[1][link, k] / a[1][link, j]),
                            10 * np.log10(a[1][link, j] / p_max[link]),
                            int(np.count_nonzero(ia[link, j])), bool(np.any(ia[link, j] == 8))))
    return np.array(out, dtype=float).reshape(-1, 5)


def consistency(traces: dict, settings: dict, ref: tuple, lm) -> dict:
    """What the path identity rests on, measured: copies of one path in two settings of the same
    tracing direction and depth (delay and power differences), of the same direction and
    different depths (Sionna RT gives a path that uses all max_depth interactions and has a
    diffraction another power than the deeper trace), in the two directions (the diffraction
    coefficient's reciprocity), and distinct paths of one interaction sequence within a
    nanosecond of each other in the reference."""
    def group(key):
        g = {}
        for n in traces:
            g.setdefault(key(settings[n]), []).append(n)
        return g
    same, deeper = [], []
    for names in group(lambda s: (s["direction"], s["max_depth"])).values():
        same += [_copies(traces[names[0]], traces[n], lm) for n in names[1:]]
    for d, names in group(lambda s: s["direction"]).items():
        by_depth = sorted({settings[n]["max_depth"] for n in names})
        for lo, hi in zip(by_depth, by_depth[1:]):
            a = next(n for n in names if settings[n]["max_depth"] == lo)
            b = next(n for n in names if settings[n]["max_depth"] == hi)
            c = _copies(traces[a], traces[b], lm)
            deeper.append(c[(c[:, 3] == lo) & (c[:, 4] > 0)])
    same = np.concatenate(same) if same else np.zeros((0, 5))
    deeper = np.concatenate(deeper) if deeper else np.zeros((0, 5))
    out = {"same_setup_pairs": len(same)}
    if len(same):
        off = np.abs(same[:, 1]) > 0.1
        out.update(same_setup_max_delay_diff_s=float(np.abs(same[:, 0]).max()),
                   same_setup_pairs_over_0p1db=int(off.sum()),
                   same_setup_over_0p1db_strongest_rel_db=float(same[off, 2].max()) if off.any() else None)
    out["full_depth_diffracted_pairs"] = len(deeper)
    if len(deeper):
        off = np.abs(deeper[:, 1]) > 0.1
        out.update(full_depth_over_0p1db_pct=100 * float(off.mean()),
                   full_depth_power_diff_db_max=float(np.abs(deeper[:, 1]).max()))
    rec = [n for n in traces if settings[n]["direction"] == "reciprocal"]
    fwd = [n for n in traces if settings[n]["direction"] == "forward"]
    if rec and fwd:
        cross = _copies(traces[rec[0]], traces[fwd[0]], lm)
        for n in rec[1:]:
            cross = np.concatenate([cross, _copies(traces[n], traces[fwd[0]], lm)])
        out["cross_direction_pairs"] = len(cross)
        if len(cross):
            dp = np.abs(cross[:, 1])
            out.update(cross_direction_power_diff_db_p50=float(np.median(dp)),
                       cross_direction_power_diff_db_max=float(dp.max()),
                       cross_direction_over_1db_pct=100 * float(np.mean(dp > 1.0)))
    tau, _, inter, valid = ref
    gaps = []
    for link in range(tau.shape[0]):
        j = np.flatnonzero(valid[link])
        t, seq = tau[link, j], inter[link, j]
        d = np.abs(t[:, None] - t[None, :])
        same_seq = np.all(seq[:, None, :] == seq[None, :, :], axis=-1)
        iu = np.triu_indices(len(j), 1)
        gaps += list(d[iu][same_seq[iu]])
    gaps = np.array(gaps)
    out["ref_same_sequence_pairs_within_1ns"] = int(np.sum(gaps <= 1e-9))
    out["ref_same_sequence_min_gap_s"] = float(gaps.min()) if gaps.size else None
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", help="config JSON (default: the built-in default)")
    ap.add_argument("--every", type=int, default=12, help="every k-th trajectory point (12)")
    ap.add_argument("--max-points", type=int, help="at most this many points")
    ap.add_argument("--settings", help="comma-separated direction:depth:rays[:nd] "
                    "(default: the built-in ladder)")
    ap.add_argument("--unions", help="comma-separated A+B rows (settings already traced)")
    ap.add_argument("--reference", default="union",
                    help="'union' (every path any setting of the config's tracing direction "
                    "found), 'union-all' (of every setting) or a setting")
    ap.add_argument("--set", action="append", default=[], metavar="PATH=JSON",
                    help="config override, e.g. propagation.raytrace.diffraction=false")
    ap.add_argument("--keep", help="folder keeping each setting's traced paths (reused)")
    ap.add_argument("--out", help="write OUT.json and OUT.md")
    ap.add_argument("--quick", action="store_true", help="4 points, a short ladder")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(Path(args.child[0]), Path(args.child[1]))
        return 0

    from veriloc_rt.config import config_to_dict, load_config
    from veriloc_rt.propagation import link_metrics as lm

    cfg_data = config_to_dict(load_config(args.config))
    for item in args.set:
        path, _, value = item.partition("=")
        cfg_data = patched(cfg_data, {path: json.loads(value)})
    if cfg_data["propagation"]["model"] != "raytrace":
        raise SystemExit("error: propagation.model: the study needs 'raytrace'")
    if args.quick:
        every, max_points = args.every, args.max_points or 4
    else:
        every, max_points = args.every, args.max_points
    specs = args.settings.split(",") if args.settings else \
        list(QUICK_SETTINGS if args.quick else DEFAULT_SETTINGS)
    unions = [u for u in args.unions.split(",") if u] if args.unions is not None else \
        list(QUICK_UNIONS if args.quick else DEFAULT_UNIONS)
    if args.reference != "union" and args.reference not in specs:
        specs.append(args.reference)
    settings = {s: parse_setting(s) for s in specs}
    for u in unions:
        for part in u.split("+"):
            if part not in settings:
                raise SystemExit(f"error: --unions: {part!r} is not among the settings")

    keep = Path(args.keep) if args.keep else None
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        geo, pts, tx, rx = build_links(cfg_data, work, every, max_points)
        digest = hashlib.sha256(json.dumps({"cfg": cfg_data, "tx": tx.round(3).tolist(),
                                            "rx": rx.round(3).tolist()}, sort_keys=True)
                                .encode()).hexdigest()[:12]
        rt = cfg_data["propagation"]["raytrace"]
        print(f"# {len(pts)} points (every {every}-th of {geo.num_points}), {len(tx)} serving "
              f"links; config {args.config or 'default'}; seed {cfg_data['seed']}; "
              f"diffraction {rt['diffraction']}; overrides {args.set or 'none'}; "
              f"config digest {digest}", flush=True)
        results = {}
        for s, setting in settings.items():
            results[s] = trace_setting(setting, cfg_data, geo.scene_xml, tx, rx, work, keep, digest)

    traces = {s: arrays(r) for s, r in results.items()}
    direction = rt["direction"]
    if args.reference in ("union", "union-all"):
        # with a non-reciprocal diffraction coefficient one path has two powers, one per
        # direction: 'union' keeps to the config's tracing direction
        members = [s for s in specs if args.reference == "union-all"
                   or settings[s]["direction"] == direction]
        if not members:
            raise SystemExit(f"error: --reference union: no setting traces '{direction}'")
        # the deepest settings first: a path that uses all max_depth interactions and reflects
        # after its diffraction gets another power from Sionna RT than the same path traced with
        # a larger max_depth (measured, docs/convergence.md); the deeper copy is kept
        members.sort(key=lambda m: -settings[m]["max_depth"])
        ref_u = lm.union_paths([traces[s] for s in members])
        ref = ref_u[:4]
        ref_name = f"union of the {'' if args.reference == 'union-all' else direction + ' '}settings"
    else:
        ref = traces[args.reference]
        ref_name = args.reference
    rows = []
    for s, r in results.items():
        m = row_metrics(traces[s], ref, lm)
        m.update(label=s, s_per_link=float(r["seconds"]) / len(tx), calls=int(r["calls"]),
                 warmup_s=float(r["warmup_s"]), peak_rss_gib=float(r["maxrss_gib"]),
                 load=[float(r["load_start"]), float(r["load_end"])])
        rows.append(m)
    if args.reference.startswith("union") and len(members) > 1:
        # how much the costliest member adds: what the union would miss without it
        top = max(members, key=lambda m: (settings[m]["rays_per_source"], settings[m]["max_depth"]))
        rest = lm.union_paths([traces[m] for m in members if m != top])[:4]
        m = row_metrics(rest, ref, lm)
        m.update(label=f"reference without {top}", s_per_link=None)
        rows.append(m)
    for u in unions:
        parts = u.split("+")
        t = lm.union_paths([traces[p] for p in parts])[:4]
        m = row_metrics(t, ref, lm)
        m.update(label=u, s_per_link=sum(float(results[p]["seconds"]) for p in parts) / len(tx))
        rows.append(m)
    if args.reference.startswith("union"):
        contrib = {s: 0 for s in members}
        for s, n in zip(*np.unique(ref_u[4][ref_u[3]], return_counts=True)):
            contrib[members[s]] = int(n)
    table = markdown(rows)
    names = [n for n in CLASS_SETTINGS if n in traces] or list(traces)[:3]
    ctable, classes = class_table(ref, traces, names, lm)
    check = consistency(traces, settings, ref, lm)
    print(f"\nreference: {ref_name}; {int(ref[3].any(-1).sum())} of {len(tx)} links with a path; "
          f"power dev = 10 log10(P / P_ref) per link (negative: power missing)\n")
    print(table)
    print("\nreference power by path class (mean over the links of the class's share of the "
          "link's power) and the share of it each setting finds:\n")
    print(ctable)
    print("\npath identity (copies: same interaction sequence, delays within "
          f"{lm.SAME_PATH_TOL_S:g} s):")
    for k, v in check.items():
        print(f"  {k}: {v:.3g}" if isinstance(v, float) else f"  {k}: {v}")
    print("timing: " + ", ".join(f"{r['label']} load {r['load'][0]:.1f}-{r['load'][1]:.1f} "
                                 f"{r['peak_rss_gib']:.1f} GiB" for r in rows if "load" in r))
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        meta = {"config": args.config or "default", "overrides": args.set, "every": every,
                "points": pts.tolist(), "links": len(tx), "reference": ref_name,
                "digest": digest, "consistency": check}
        if args.reference.startswith("union"):
            meta["union_paths_first_found_by"] = contrib
        out.with_suffix(".json").write_text(json.dumps(
            {"meta": meta, "rows": rows, "classes": classes}, indent=2))
        out.with_suffix(".md").write_text(
            f"reference: {ref_name}, {len(tx)} links\n\n{table}\n\n{ctable}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
