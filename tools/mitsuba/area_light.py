#!/usr/bin/env python3
"""Mitsuba 3's pictures of the area-light test scenes in tests/projects/mitsuba.

    pip install mitsuba numpy
    python3 tools/mitsuba/area_light.py [SCENE] [SPP]

SCENE is a folder of tests/projects/mitsuba (default area_sphere_floor):

- area_sphere_floor: a 2 × 2 m painted panel 2.5 m up, facing down, over a sphere on a 20 m
  floor; from the project's "main" camera, and from its "far" camera (the floor 5–10 m from the
  light, beyond the reach of its top face: 4 × 2.5 m / 2 from the panel's edge).
- area_tilted: a 2 × 1 m painted panel 1.8 m up, turned −90° and tilted 50° (Lightloom's
  `angle` and `tilt`: the tilt about the light's width axis, then the turn about +y), facing the
  +x side of the floor, over a sphere and a box.

Each renders the folder's project.ron with Mitsuba 3 (scalar_rgb, no LLVM needed): the same
cameras, Lambert surfaces of albedo 0.64 (Lightloom's 0.8 object colour times the 0.8 default
material), and the panel as a one-sided `rectangle` area emitter whose radiance is panel.png
(sRGB, as Lightloom's import reads a PNG). The `direct` integrator: direct light only, as
Lightloom's area lights are, with the panel hidden from the camera. Writes mitsuba.exr (and mitsuba_far.exr) beside the project, half
float, which tests/area_light_cli.rs compares Lightloom's renders with.
"""
import sys
from pathlib import Path

import mitsuba as mi

mi.set_variant("scalar_rgb")
name = sys.argv[1] if len(sys.argv) > 1 else "area_sphere_floor"
here = Path(__file__).resolve().parents[2] / "tests/projects/mitsuba" / name
spp = int(sys.argv[2]) if len(sys.argv) > 2 else 4096
T = mi.ScalarTransform4f


def sensor(origin, target, fov=40.0):
    return {
        "type": "perspective", "fov": fov, "fov_axis": "y",
        "to_world": T().look_at(origin=origin, target=target, up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": 320, "height": 180, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": spp},
    }


def panel(centre, width, depth, angle=0.0, tilt=0.0):
    """Lightloom's area light: Mitsuba's rectangle spans [-1, 1]² in xy facing +z; a quarter
    turn about x lays it level facing down (its y along the light's depth, z), then the tilt
    about the width axis (x) and the turn about +y, as Lightloom orients it."""
    to_world = (T().translate(centre).rotate([0, 1, 0], angle).rotate([1, 0, 0], tilt)
                .rotate([1, 0, 0], 90).scale([width / 2, depth / 2, 1]))
    return {
        "type": "rectangle",
        "to_world": to_world,
        # Nearest texel lookups, as Lightloom's import fills its 64² texture 1:1.
        "emitter": {
            "type": "area",
            "radiance": {"type": "bitmap", "filename": str(here / "panel.png"), "filter_type": "nearest"},
        },
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
    }


lambert = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.64, 0.64, 0.64]}}
floor = {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale([10, 10, 1]), "bsdf": lambert}
scenes = {
    "area_sphere_floor": {
        "main": sensor([0, 1.6, 6.0], [0, 0.2, 0]),
        "far": sensor([0, 1.5, -3.5], [0, 0, -9.5]),
        "floor": floor,
        "sphere": {"type": "sphere", "center": [0.7, 0.6, -0.3], "radius": 0.6, "bsdf": lambert},
        "panel": panel([0, 2.5, 0], 2.0, 2.0),
    },
    "area_tilted": {
        "main": sensor([1.5, 2.4, 6.5], [0.6, 0.3, 0.0], fov=45.0),
        "floor": floor,
        "sphere": {"type": "sphere", "center": [0.4, 0.6, 0.3], "radius": 0.6, "bsdf": lambert},
        "box": {"type": "cube", "to_world": T().translate([1.2, 0.45, -1.4]).scale([0.3, 0.45, 0.3]), "bsdf": lambert},
        "panel": panel([-1.6, 1.8, 0.0], 2.0, 1.0, angle=-90.0, tilt=50.0),
    },
}
scene = mi.load_dict({
    "type": "scene",
    # The panel itself is hidden from the camera, as Lightloom does not draw it.
    "integrator": {"type": "direct", "emitter_samples": 4, "bsdf_samples": 0, "hide_emitters": True},
    **scenes[name],
})
for camera in scene.sensors():
    out = here / {"main": "mitsuba.exr", "far": "mitsuba_far.exr"}[camera.id()]
    image = mi.render(scene, sensor=camera)
    bitmap = mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float16)
    bitmap.write(str(out))
    print(f"wrote {out} ({spp} spp)")
