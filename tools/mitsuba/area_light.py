#!/usr/bin/env python3
"""Mitsuba 3's picture of tests/projects/mitsuba/area_sphere_floor, the area-light test scene.

    pip install mitsuba numpy
    python3 tools/mitsuba/area_light.py [SPP]

Renders the scene of that folder's project.ron with Mitsuba 3 (scalar_rgb, no LLVM needed): the
same camera, a 20 m diffuse floor and a sphere of albedo 0.64 (Lightloom's 0.8 object colour
times the 0.8 default material), and the panel as a one-sided `rectangle` area emitter facing
down whose radiance is panel.png (sRGB, as Lightloom's import reads a PNG). The `direct`
integrator: direct light only, as Lightloom's area lights are. Writes mitsuba.exr and, from the
project's "far" camera, mitsuba_far.exr (half float) beside the project, which
tests/area_light_cli.rs compares Lightloom's renders with.
"""
import sys
from pathlib import Path

import mitsuba as mi

mi.set_variant("scalar_rgb")
here = Path(__file__).resolve().parents[2] / "tests/projects/mitsuba/area_sphere_floor"
spp = int(sys.argv[1]) if len(sys.argv) > 1 else 4096
T = mi.ScalarTransform4f
def sensor(origin, target):
    return {
        "type": "perspective", "fov": 40.0, "fov_axis": "y",
        "to_world": T().look_at(origin=origin, target=target, up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": 320, "height": 180, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": spp},
    }


lambert = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.64, 0.64, 0.64]}}
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "direct", "emitter_samples": 4, "bsdf_samples": 0},
    "main": sensor([0, 1.6, 6.0], [0, 0.2, 0]),
    # The project's "far" camera: the floor 5–10 m from the light, beyond the reach of its top
    # face (4 × 2.5 m / 2 from the panel's edge), lit there only by the part beyond the face.
    "far": sensor([0, 1.5, -3.5], [0, 0, -9.5]),
    # Mitsuba's rectangle spans [-1, 1]² in xy, facing +z.
    "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale([10, 10, 1]), "bsdf": lambert},
    "sphere": {"type": "sphere", "center": [0.7, 0.6, -0.3], "radius": 0.6, "bsdf": lambert},
    "panel": {
        "type": "rectangle",
        "to_world": T().translate([0, 2.5, 0]).rotate([1, 0, 0], 90),
        # Nearest texel lookups, as Lightloom's import fills its 64² texture 1:1.
        "emitter": {
            "type": "area",
            "radiance": {"type": "bitmap", "filename": str(here / "panel.png"), "filter_type": "nearest"},
        },
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
    },
})
for sensor in scene.sensors():
    name = {"main": "mitsuba.exr", "far": "mitsuba_far.exr"}[sensor.id()]
    image = mi.render(scene, sensor=sensor)
    bitmap = mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float16)
    bitmap.write(str(here / name))
    print(f"wrote {here / name} ({spp} spp)")
