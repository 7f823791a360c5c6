#!/usr/bin/env python3
"""The sun's highlight of a far pixel of a normal-mapped GGX floor: the mean over the map's texels
of the reference's shading, against the viewport's per-lobe formula (shaders/sun.wgsl
`sun_lobe_through`) on a vMF mixture fitted to the whole map, as a pixel covering every texel sees.

    pip install numpy pillow
    python3 tools/normal_map_far_field.py [MAP.png]

The default map is the grazing test's dimples (tests/projects/mitsuba/grazing_hammered), GGX
α 0.09, Fresnel 1, the camera 1 m above the floor; the sun swept over 41 azimuths × 3
elevations about the highlight at four distances. Prints per distance the relative RMS error over
the sweep and the energy (sum over the truth's), for each formula and lobe count:
- "at the mean": every factor of the BRDF at the lobe's mean, masked by the widened lobe, a lobe
  the view lies below black (the formula before);
- "reflecting normal": the widened distribution about the mean, the rest at n* ∝ κ_b h + κ μ,
  masked by the material's own roughness, the part of the lobe below the view flipped, with the
  shadow terminator;
- "GGX ⊗ vMF": the same with the widened distribution a mix of the widened GGX and a Beckmann
  lobe of the same width, by the normals' share of the slope variance (the formula now).
"""
import sys
from math import erf, exp, pi, sqrt
from pathlib import Path

import numpy as np
from PIL import Image

ALPHA = 0.09
UP = np.array([0.0, 1.0, 0.0])
here = Path(__file__).resolve().parents[1]
path = sys.argv[1] if len(sys.argv) > 1 else here / "tests/projects/mitsuba/grazing_hammered/dimples.png"
texels = np.asarray(Image.open(path).convert("RGB"), float).reshape(-1, 3) / 127.5 - 1.0
texels /= np.linalg.norm(texels, axis=1, keepdims=True)
# Tangent space (x, y, z = normal) to the world: the floor's normal is +y.
NORMALS = np.stack([texels[:, 0], texels[:, 2], -texels[:, 1]], 1)


def lam(cos, a):
    c2 = np.maximum(cos * cos, 1e-12)
    return (-1 + np.sqrt(1 + a * a * (1 - c2) / c2)) / 2


def ggx_d(ch, a):
    return np.where(ch > 0, a * a / (pi * ((ch * ch) * (a * a - 1) + 1) ** 2), 0.0)


def terminator(n, wi):
    c2 = np.maximum((n @ UP) ** 2, 1e-12)
    a2 = np.minimum((1 - c2) / c2 / 8, 1)
    return 2 / (1 + np.sqrt(1 + a2 * (1 - wi[1] ** 2) / wi[1] ** 2))


def truth(wi, wo):
    """The reference: each texel's normal, flipped where the view lies below it, f·cos·terminator."""
    n = NORMALS.copy()
    below = (n @ wo) <= 0
    n[below] = 2 * (n[below] @ UP)[:, None] * UP - n[below]
    ci, co = n @ wi, n @ wo
    h = (wi + wo) / np.linalg.norm(wi + wo)
    f = ggx_d(n @ h, ALPHA) / (1 + lam(ci, ALPHA) + lam(co, ALPHA)) / (4 * np.maximum(co, 1e-9))
    return np.where((ci > 0) & (co > 0), f * terminator(n, wi), 0.0).mean()


def fit_vmf(x, k, iterations=60):
    """Spherical EM (Banerjee et al. 2005), seeded on the flat normal and the farthest normals."""
    seeds = [UP]
    while len(seeds) < k:
        seeds.append(x[np.argmax(np.min(np.stack([1 - x @ s for s in seeds], 1), 1))])
    mu, kappa, w = np.array(seeds), np.full(k, 10.0), np.full(k, 1 / k)
    for _ in range(iterations):
        log_norm = np.log(kappa) - np.log(2 * pi) - kappa - np.log1p(-np.exp(-2 * kappa))
        r = np.log(w) + log_norm + (x @ mu.T) * kappa
        r = np.exp(r - r.max(1, keepdims=True))
        r /= r.sum(1, keepdims=True)
        mass, resultant = r.sum(0), r.T @ x
        length = np.linalg.norm(resultant, axis=1)
        w, mu = mass / len(x), resultant / length[:, None]
        c = np.clip(length / mass, 0, 1 - 1e-9)
        kappa = np.minimum((3 * c - c ** 3) / (1 - c * c), 1e6)
    return list(zip(w, mu, kappa))


def phi_cdf(t):
    return 0.5 * (1 + erf(t / sqrt(2)))


def seen_parts(mu, kappa, wo):
    """shaders/normal_map.wgsl `ndf_seen_parts`: (share, mean) above the view, and below, flipped."""
    m = mu @ wo
    across = sqrt(max(1 - m * m, 0.0))
    sigma = across / sqrt(max(kappa, 1e-9))
    if sigma < 1e-6 or across < 1e-6 or kappa >= 1e5:
        return [(1.0, mu)] if m > 0 else [(1.0, 2 * (mu @ UP) * UP - mu)]
    z, towards = m / sigma, wo - m * mu
    below = 1 - phi_cdf(z)
    parts = []
    for share, sign, flip in [(1 - below, 1.0, False), (below, -1.0, True)]:
        if share < 1e-4:
            continue
        shift = sign * sigma * exp(-0.5 * z * z) / sqrt(2 * pi) / share
        mean = mu + towards / across * (shift / across)
        mean /= np.linalg.norm(mean)
        parts.append((share, 2 * (mean @ UP) * UP - mean if flip else mean))
    return parts


def at_the_mean(lobes, wi, wo):
    total = 0.0
    for w, mu, kappa in lobes:
        wide = sqrt(ALPHA ** 2 + 2 / kappa)
        ci, co = mu @ wi, mu @ wo
        h = (wi + wo) / np.linalg.norm(wi + wo)
        if ci > 0 and co > 0:
            total += w * ggx_d(mu @ h, wide) / (1 + lam(ci, wide) + lam(co, wide)) / (4 * co)
    return total


def beckmann_d(ch, a):
    c2 = np.maximum(ch * ch, 1e-12)
    return np.where(ch > 0, np.exp(-(1 - c2) / c2 / (a * a)) / (pi * a * a * c2 * c2), 0.0)


def convolved(lobes, wi, wo):
    return reflecting_normal(lobes, wi, wo, mixed=True)


def reflecting_normal(lobes, wi, wo, mixed=False):
    total = 0.0
    h = (wi + wo) / np.linalg.norm(wi + wo)
    for w, mu0, kappa in lobes:
        wide = sqrt(ALPHA ** 2 + 2 / kappa)
        spread = (2 / kappa) / wide ** 2 if mixed else 0.0
        for share, mu in seen_parts(mu0, kappa, wo):
            star = mu if kappa >= 1e5 else (2 / ALPHA ** 2 * h + kappa * mu) / np.linalg.norm(2 / ALPHA ** 2 * h + kappa * mu)
            ci, co = star @ wi, star @ wo
            if ci > 0 and co > 0 and wi[1] > 0:
                d = (1 - spread) * ggx_d(mu @ h, wide) + spread * beckmann_d(mu @ h, wide)
                f = d / (1 + lam(ci, ALPHA) + lam(co, ALPHA)) / (4 * co)
                total += w * share * f * terminator(star, wi)
    return total


def sweep(formula, lobes):
    figures = []
    for distance in [2.75, 4.5, 9.0, 20.0]:
        wo = np.array([0.0, 1.0, distance]) / np.hypot(1.0, distance)
        ours, exact = [], []
        for azimuth in np.radians(np.linspace(-20, 20, 41)):
            for elevation in np.radians([10.0, 12.0, 14.0]):
                wi = np.array([np.sin(azimuth) * np.cos(elevation), np.sin(elevation), -np.cos(azimuth) * np.cos(elevation)])
                ours.append(formula(lobes, wi, wo))
                key = (distance, azimuth, elevation)
                if key not in TRUTH:
                    TRUTH[key] = truth(wi, wo)
                exact.append(TRUTH[key])
        ours, exact = np.array(ours), np.array(exact)
        figures.append((np.sqrt(((ours - exact) ** 2).mean()) / exact.mean(), ours.sum() / exact.sum()))
    return figures


TRUTH = {}
print("far pixel of", path, "- per distance 2.75, 4.5, 9, 20 m: relative RMS error / energy")
for k in [6, 12, 24]:
    lobes = fit_vmf(NORMALS, k)
    for name, formula in [("at the mean", at_the_mean), ("reflecting normal", reflecting_normal), ("GGX ⊗ vMF", convolved)]:
        row = " ".join(f"{e * 100:5.1f}% / {x:.3f}" for e, x in sweep(formula, lobes))
        print(f"{k:2} lobes, {name:18} {row}")
