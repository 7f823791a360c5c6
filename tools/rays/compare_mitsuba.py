#!/usr/bin/env python3
"""Trace Lightloom's visibility rays with Mitsuba 3 (Embree underneath) and compare.

    cargo run --release -- bench --only rays --rays-dump /tmp/rays
    python3 tools/rays/compare_mitsuba.py /tmp/rays

`lightloom bench --only rays --rays-dump DIR` writes the engine model as `scene.ply` and, per
direction count, `rays_N.bin` (f32 records: origin xyz, direction xyz, Lightloom's blocked
flag) and `rays_N.json` (Lightloom's best-of-3 times). This script traces the bit-identical
rays with `Scene.ray_test` (occlusion, t in (0, inf)) in Mitsuba's LLVM variant (all cores,
as Lightloom uses all cores), prints both rates, their ratio, and the rays on which the two
disagree. Needs `pip install mitsuba` and Debian's libllvm19 (DRJIT_LIBLLVM_PATH is set here
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


def main(folder: Path, runs: int = 5) -> int:
    mi.set_variant("llvm_ad_rgb")
    scene = mi.load_dict({"type": "scene", "mesh": {"type": "ply", "filename": str(folder / "scene.ply")}})
    print(f"Mitsuba {mi.__version__} ({mi.variant()}), Embree through Scene.ray_test")
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
        worst = max(worst, differ / n)
        print(f"  {path.stem}: {n} rays ({100 * ours.mean():.0f}% blocked), {meta['receivers']} receivers")
        print(f"    Embree (Mitsuba ray_test, best of {runs}): {embree:.2f} M rays/s")
        print(f"    Lightloom bundles: {lightloom:.2f} M rays/s = {lightloom / embree:.2f}x Embree "
              f"(one ray at a time: {single:.2f} M rays/s = {single / embree:.2f}x)")
        print(f"    disagree on {differ} rays ({100 * differ / n:.4f}%): {only_ours} blocked only for Lightloom, "
              f"{differ - only_ours} only for Embree")
    return 0 if worst < 0.0005 else 1


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1])))
