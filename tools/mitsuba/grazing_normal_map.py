#!/usr/bin/env python3
"""Mitsuba 3's picture of tests/projects/mitsuba/grazing_hammered (or, with --ribbed,
grazing_ribbed), the normal-map test scenes.

    pip install mitsuba numpy
    python3 tools/mitsuba/grazing_normal_map.py [SPP] [--ribbed]

With --ribbed the map is ribs.png instead of dimples.png: diagonal ribs, 8 across each tile's
edge (a sinusoid, sloping up to 25°), so the normals spread along one axis, at 45° to the view.

Writes the scene's inputs beside its project.ron, then renders it:

- dimples.png (ribs.png with --ribbed): a 256² tangent-space normal map (OpenGL convention, +Y up the image, n = 2·rgb − 1)
  of hammered dimples: spherical caps whose rims slope at up to 24°, on a jittered grid, flat
  between them. Tiled 80 times over the 40 m plane: 2 mm per texel.
- sky.exr and sky_mitsuba.exr: one sky sampled at each renderer's pixel positions (Lightloom
  reads column j, row i of an equirectangular map at u = (j + ½)/width, v = (i + ½)/height with
  u = ½ + atan2(x, −z)/2π; Mitsuba 3.9's envmap at u = (j + ½)/width, v = i/(height − 1) with
  u = atan2(x, −z)/2π: its first and last rows sit on the poles; sampled at j/(width − 1), the
  sun would straddle a repeated seam column and shine 11% too bright): a blue gradient to a bright horizon, grey ground, and a sun of about
  1.5° radius 12° up, straight ahead of the camera (toward −z).
- mitsuba.exr: a 40 m plane of GGX metal (α 0.09, Fresnel 1: `roughconductor` with material
  `none`, inside `normalmap` with raw texel values) seen from 1 m above it, looking along it
  toward the sun, lit by the sky alone through the `direct` integrator, at 320 × 180, half float.
"""
import sys
from pathlib import Path

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
ribbed = "--ribbed" in sys.argv
numbers = [a for a in sys.argv[1:] if not a.startswith("--")]
here = Path(__file__).resolve().parents[2] / "tests/projects/mitsuba" / ("grazing_ribbed" if ribbed else "grazing_hammered")
map_name = "ribs.png" if ribbed else "dimples.png"
spp = int(numbers[0]) if numbers else 1024

size, cells = 256, 6
normals = np.zeros((size, size, 3))
normals[..., 2] = 1.0
ys, xs = np.mgrid[0:size, 0:size] + 0.5
# The ribbed map: diagonal ribs, 8 across each edge, h = sin(2π·8(x + y)/size), sloping up to 25°.
# Image rows run down (+Y of the map is up the image), so n ∝ (−∂h/∂x, ∂h/∂y, 1).
slope = np.tan(np.radians(25.0)) / np.sqrt(2.0) * np.cos(2.0 * np.pi * 8.0 * (xs + ys) / size)
if ribbed:
    normals = np.stack([-slope, slope, np.ones_like(slope)], -1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
# The hammered map: one dimple per cell of a 6 × 6 grid, its centre jittered and its radius varied.
rng = np.random.default_rng(3)
covered = np.zeros((size, size), bool) if not ribbed else np.ones((size, size), bool)
rim = np.sin(np.radians(24.0))
for cy in range(cells if not ribbed else 0):
    for cx in range(cells):
        pitch = size / cells
        centre = ((cx + 0.5 + rng.uniform(-0.2, 0.2)) * pitch, (cy + 0.5 + rng.uniform(-0.2, 0.2)) * pitch)
        base = pitch * rng.uniform(0.38, 0.48)
        radius = base / rim
        # Offsets wrap, so the map tiles seamlessly.
        dx = (xs - centre[0] + size / 2) % size - size / 2
        dy = (ys - centre[1] + size / 2) % size - size / 2
        inside = (dx * dx + dy * dy < base * base) & ~covered
        # A dimple is the bottom of a sphere centred above the plane: its normal points to the
        # centre. Image rows run down (+Y of the map is up the image).
        h = np.sqrt(np.maximum(radius * radius - dx * dx - dy * dy, 0.0))
        normals[inside] = np.stack([-dx, dy, h], -1)[inside] / radius
        covered |= inside
texels = np.round((normals * 0.5 + 0.5) * 255.0).clip(0, 255).astype(np.uint8)
mi.Bitmap(texels, pixel_format=mi.Bitmap.PixelFormat.RGB).write(str(here / map_name))

# The sky, as a function of direction.
width, height = 1024, 512
sun = np.array([0.0, np.sin(np.radians(12.0)), -np.cos(np.radians(12.0))])


def sky(directions):
    y = directions[..., 1]
    colour = np.where(
        (y > 0.0)[..., None],
        np.array([0.45, 0.6, 1.0]) * (1.4 - 0.8 * np.clip(y, 0.0, 1.0))[..., None],
        np.array([0.15, 0.15, 0.15]),
    )
    angle = np.degrees(np.arccos(np.clip(directions @ sun, -1.0, 1.0)))
    t = np.clip((1.8 - angle) / 0.6, 0.0, 1.0)
    fade = (t * t * (3.0 - 2.0 * t))[..., None]
    return (1.0 - fade) * colour + fade * np.array([3000.0, 2850.0, 2550.0])


def directions(u, v, offset):
    phi = (u - offset) * 2.0 * np.pi
    theta = v * np.pi
    return np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], -1)


for name, (u, v, offset) in {
    "sky.exr": ((np.arange(width) + 0.5) / width, (np.arange(height) + 0.5) / height, 0.5),
    "sky_mitsuba.exr": ((np.arange(width) + 0.5) / width, np.arange(height) / (height - 1), 0.0),
}.items():
    uu, vv = np.meshgrid(u, v)
    image = sky(directions(uu, vv, offset)).astype(np.float32)
    mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float16).write(str(here / name))

T = mi.ScalarTransform4f
metal = {
    "type": "normalmap",
    "normalmap": {"type": "bitmap", "filename": str(here / map_name), "raw": True,
                  "filter_type": "bilinear", "to_uv": mi.ScalarTransform3f().scale([80.0, -80.0])},
    "bsdf": {"type": "roughconductor", "material": "none", "distribution": "ggx", "alpha": 0.09},
}
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "direct", "emitter_samples": 2, "bsdf_samples": 2},
    "sensor": {
        "type": "perspective", "fov": 40.0, "fov_axis": "y",
        "to_world": T().look_at(origin=[0, 1.0, 10.0], target=[0, 0.4, -10.0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": 320, "height": 180, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": spp},
    },
    # Mitsuba's rectangle spans [-1, 1]² in xy facing +z, its uv [0, 1]² from (-1, -1).
    "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale([20, 20, 1]), "bsdf": metal},
    "sky": {"type": "envmap", "filename": str(here / "sky_mitsuba.exr")},
})
image = np.array(mi.render(scene))
mi.Bitmap(image.astype(np.float32)).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float16).write(
    str(here / "mitsuba.exr"))
print(f"wrote {here / 'mitsuba.exr'} ({spp} spp)")
