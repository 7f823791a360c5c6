#!/usr/bin/env python3
"""Trace Lightloom's visibility rays with Mitsuba 3 (Embree underneath) and compare.

    cargo run --release -- bench --only rays --rays-dump /tmp/rays
    python3 tools/rays/compare_mitsuba.py /tmp/rays

`lightloom bench --only rays --rays-dump DIR` writes the engine model as `scene.ply` and, per
direction count, `rays_N.bin` (f32 records: origin xyz, direction xyz, Lightloom's blocked
flag) and `rays_N.json` (Lightloom's best-of-3 times). This script traces the bit-identical
rays with `Scene.ray_test` (occlusion, t in (0, inf)) in Mitsuba's LLVM variant (all cores,
as Lightloom uses all cores), prints both rates, their ratio, the rays on which the two
disagree, and which side f64 brute force sides with on those rays. Fails (exit 1) when
Lightloom is wrong on 0.05% of the rays or more. Needs `pip install mitsuba` and Debian's libllvm19 (DRJIT_LIBLLVM_PATH is set here
when unset).
"""
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402


def read_ply(path: Path):
    """The triangles of our binary PLY (float xyz, uchar count + int indices) in f64."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    count = lambda what: int(next(l for l in header if l.startswith("element " + what)).split()[-1])
    vertices, faces = count("vertex"), count("face")
    positions = np.frombuffer(data[end:end + 12 * vertices], dtype="<f4").reshape(-1, 3).astype(np.float64)
    records = np.frombuffer(data[end + 12 * vertices:], dtype=np.uint8).reshape(faces, 13)
    indices = records[:, 1:].copy().view("<i4").reshape(faces, 3)
    return positions[indices[:, 0]], positions[indices[:, 1]], positions[indices[:, 2]]


def exact_blocked(triangles, origin, direction) -> bool:
    """Brute force in f64 over every triangle: a hit with u, v, w >= 0 at t > 0 (a surface
    through the origin, t = 0, does not block)."""
    v0, v1, v2 = triangles
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = origin - v0
        u = np.einsum("ij,ij->i", s, p) / det
        q = np.cross(s, e1)
        v = (q @ direction) / det
        t = np.einsum("ij,ij->i", e2, q) / det
        return bool(np.any((det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)))


def main(folder: Path, runs: int = 5) -> int:
    mi.set_variant("llvm_ad_rgb")
    scene = mi.load_dict({"type": "scene", "mesh": {"type": "ply", "filename": str(folder / "scene.ply")}})
    print(f"Mitsuba {mi.__version__} ({mi.variant()}), Embree through Scene.ray_test")
    triangles = read_ply(folder / "scene.ply")
    worst = 0.0
    for path in sorted(folder.glob("rays_*.bin"), key=lambda p: int(p.stem.split("_")[1])):
        records = np.fromfile(path, dtype="<f4").reshape(-1, 7)
        ours = records[:, 6] > 0.5
        meta = json.loads(path.with_suffix(".json").read_text())
        rays = mi.Ray3f(mi.Point3f(*[records[:, k].copy() for k in range(3)]),
                        mi.Vector3f(*[records[:, k].copy() for k in range(3, 6)]))
        best = float("inf")
        for _ in range(runs):
            start = time.perf_counter()
            blocked = scene.ray_test(rays)
            dr.eval(blocked)
            dr.sync_thread()
            best = min(best, time.perf_counter() - start)
        theirs = np.array(blocked, dtype=bool)
        n = len(records)
        differ = int(np.count_nonzero(theirs != ours))
        only_ours = int(np.count_nonzero(ours & ~theirs))
        embree = n / best / 1e6
        lightloom = n / meta["lightloom_bundle_seconds"] / 1e6
        single = n / meta["lightloom_single_seconds"] / 1e6
        # Who is right where they differ: f64 brute force (up to 2,000 of the rays).
        disputed = np.nonzero(theirs != ours)[0][:2000]
        wrong_ours = wrong_theirs = 0
        for i in disputed:
            truth = exact_blocked(triangles, records[i, :3].astype(np.float64), records[i, 3:6].astype(np.float64))
            wrong_ours += truth != ours[i]
            wrong_theirs += truth != theirs[i]
        scale = differ / max(len(disputed), 1)
        worst = max(worst, wrong_ours * scale / n)
        print(f"  {path.stem}: {n} rays ({100 * ours.mean():.0f}% blocked), {meta['receivers']} receivers")
        print(f"    Embree (Mitsuba ray_test, best of {runs}): {embree:.2f} M rays/s")
        print(f"    Lightloom bundles: {lightloom:.2f} M rays/s = {lightloom / embree:.2f}x Embree "
              f"(one ray at a time: {single:.2f} M rays/s = {single / embree:.2f}x)")
        print(f"    disagree on {differ} rays ({100 * differ / n:.4f}%): {only_ours} blocked only for Lightloom, "
              f"{differ - only_ours} only for Embree")
        print(f"    against f64 brute force on {len(disputed)} of them: Lightloom wrong on {wrong_ours}, "
              f"Embree wrong on {wrong_theirs} (about {100 * wrong_ours * scale / n:.4f}% and "
              f"{100 * wrong_theirs * scale / n:.4f}% of all rays)")
    return 0 if worst < 0.0005 else 1


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1])))
