#!/usr/bin/env python3
"""Mitsuba 3's picture of tests/projects/mitsuba/sun_zenith_sphere, the square-light test scene.

    pip install mitsuba numpy
    python3 tools/mitsuba/sun_zenith.py [SPP]

Writes the scene's environment, sky.exr (an equirectangular sky, symmetric about the vertical
so no axis convention can differ between renderers: a gradient from a blue zenith to a bright
horizon, grey ground below, and a sun of about 1.6 degrees radius at the zenith, about three
times the sky's irradiance) and the same sky in Mitsuba's pixel convention, then renders the scene of that folder's project.ron with Mitsuba 3
(scalar_rgb): the same camera, a diffuse sphere (r 0.75, albedo 0.64: Lightloom's 0.8 object
colour times the 0.8 default material) on an 8 m diffuse floor, lit by the `envmap` alone
through the `direct` integrator (direct light only, as Lightloom's modes are). Writes
mitsuba.exr (half float) and surfaces.png (white where a surface is seen) beside the project,
which tests/accuracy_cli.rs compares Lightloom's renders with.
"""
import sys
from pathlib import Path

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
here = Path(__file__).resolve().parents[2] / "tests/projects/mitsuba/sun_zenith_sphere"
spp = int(sys.argv[1]) if len(sys.argv) > 1 else 1024

# The sky as a function of the angle from the zenith: a gradient from a blue zenith to a bright
# horizon, grey ground below, and a sun at the zenith, full out to 1.2 degrees and fading
# smoothly to nothing at 2 degrees (a sharp edge at the pole would move with each renderer's
# pixel convention). Lightloom reads row i of an equirectangular map at the angle
# (i + 0.5) 180 / height; Mitsuba 3's envmap at i 180 / (height - 1) (its first and last rows
# sit on the poles), so each gets the same function sampled at its own rows.
width, height = 1024, 512


def sky_rows(zenith_deg):
    elevation = 90.0 - zenith_deg
    up = np.clip(np.sin(np.radians(elevation)), 0.0, 1.0)
    sky = np.where(
        (elevation > 0.0)[:, None],
        np.array([0.45, 0.6, 1.0])[None, :] * (1.4 - 0.8 * up)[:, None],
        np.array([0.15, 0.15, 0.15])[None, :],
    )
    t = np.clip((2.0 - zenith_deg) / 0.8, 0.0, 1.0)
    fade = (t * t * (3.0 - 2.0 * t))[:, None]
    return (1.0 - fade) * sky + fade * np.array([3000.0, 2850.0, 2550.0])[None, :]


for name, zenith in [
    ("sky.exr", (np.arange(height) + 0.5) / height * 180.0),
    ("sky_mitsuba.exr", np.arange(height) / (height - 1) * 180.0),
]:
    image = np.repeat(sky_rows(zenith)[:, None, :], width, axis=1).astype(np.float32)
    mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float16).write(str(here / name))

T = mi.ScalarTransform4f
lambert = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.64, 0.64, 0.64]}}
scene = mi.load_dict({
    "type": "scene",
    "integrator": {
        "type": "aov",
        "aovs": "dd.y:depth",
        "light": {"type": "direct", "emitter_samples": 2, "bsdf_samples": 2},
    },
    "sensor": {
        "type": "perspective", "fov": 40.0, "fov_axis": "y",
        "to_world": T().look_at(origin=[0, 2.0, 5.0], target=[0, 0.5, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": 320, "height": 180, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": spp},
    },
    # Mitsuba's rectangle spans [-1, 1]² in xy, facing +z.
    "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale([4, 4, 1]), "bsdf": lambert},
    "sphere": {"type": "sphere", "center": [0, 0.75, 0], "radius": 0.75, "bsdf": lambert},
    "sky": {"type": "envmap", "filename": str(here / "sky_mitsuba.exr")},
})
result = np.array(mi.render(scene))
rgb, depth = result[..., :3], result[..., -1]
mi.Bitmap(rgb.astype(np.float32)).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float16).write(
    str(here / "mitsuba.exr"))
surfaces = np.where(depth > 0.0, 255, 0).astype(np.uint8)
mi.Bitmap(surfaces).write(str(here / "surfaces.png"))
print(f"wrote sky.exr, mitsuba.exr ({spp} spp) and surfaces.png in {here}")
