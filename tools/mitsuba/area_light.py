#!/usr/bin/env python3
"""Mitsuba 3's picture of tests/projects/mitsuba/area_sphere_floor, the area-light test scene.

    pip install mitsuba numpy
    python3 tools/mitsuba/area_light.py [SPP]

Renders the scene of that folder's project.ron with Mitsuba 3 (scalar_rgb, no LLVM needed): the
same camera, a 20 m diffuse floor and a sphere of albedo 0.64 (Lightloom's 0.8 object colour
times the 0.8 default material), and the panel as a one-sided `rectangle` area emitter facing
down whose radiance is panel.png (sRGB, as Lightloom's import reads a PNG). The `direct`
integrator: direct light only, as Lightloom's area lights are. Writes mitsuba.exr (half float)
beside the project, which tests/area_light_cli.rs compares Lightloom's render with.
"""
import sys
from pathlib import Path

import mitsuba as mi

mi.set_variant("scalar_rgb")
here = Path(__file__).resolve().parents[2] / "tests/projects/mitsuba/area_sphere_floor"
spp = int(sys.argv[1]) if len(sys.argv) > 1 else 1024
T = mi.ScalarTransform4f
lambert = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.64, 0.64, 0.64]}}
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "direct", "emitter_samples": 4, "bsdf_samples": 0},
    "sensor": {
        "type": "perspective", "fov": 40.0, "fov_axis": "y",
        "to_world": T().look_at(origin=[0, 1.6, 6.0], target=[0, 0.3, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": 320, "height": 180, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": spp},
    },
    # Mitsuba's rectangle spans [-1, 1]² in xy, facing +z.
    "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale([10, 10, 1]), "bsdf": lambert},
    "sphere": {"type": "sphere", "center": [0, 0.6, 0], "radius": 0.6, "bsdf": lambert},
    "panel": {
        "type": "rectangle",
        "to_world": T().translate([0, 2.5, 0]).rotate([1, 0, 0], 90),
        "emitter": {"type": "area", "radiance": {"type": "bitmap", "filename": str(here / "panel.png")}},
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
    },
})
image = mi.render(scene)
bitmap = mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float16)
bitmap.write(str(here / "mitsuba.exr"))
print(f"wrote {here / 'mitsuba.exr'} ({spp} spp)")
