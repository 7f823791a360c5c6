//! Node previews in the editor: each kind declares its [`PreviewSpec`]s (what stages they
//! read, how the picture is made), and this module makes the pictures: environment
//! thumbnails, SH lighting spheres, fog glows. The lighting math stays here; the editor only
//! shows the pixels (or plots a BRDF lobe's curves).

use crate::cubemap::{CubeMap, equirect_uv_to_dir};
pub use crate::picture::srgb_to_linear;
pub use crate::picture::{Preview, PreviewImage};
use crate::sh::{ShBasis, ShRgb};
use glam::DVec3;

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Reinhard on `scale × linear`, then the sRGB transfer function.
pub fn display_rgb8(linear: [f64; 3], scale: f64) -> [u8; 4] {
    let encode = |v: f64| {
        let v = (v * scale).max(0.0);
        let v = v / (1.0 + v);
        let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
        (s * 255.0).round().clamp(0.0, 255.0) as u8
    };
    [encode(linear[0]), encode(linear[1]), encode(linear[2]), 255]
}

/// Exposure that maps the mean luminance to middle grey (0.18 before the tone curve).
pub fn auto_scale(values: impl Iterator<Item = [f64; 3]>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), c| (s + luminance(c).max(0.0), n + 1));
    let mean = sum / n.max(1) as f64;
    if mean > 1e-12 && mean.is_finite() { 0.18 / mean } else { 1.0 }
}

/// A `width × height` equirectangular thumbnail of a radiance cube map (the README's
/// equirect convention: the centre looks down -Z, the top row is +Y), auto-exposed.
pub fn environment_thumbnail(cube: &CubeMap, width: usize, height: usize) -> PreviewImage {
    let (width, height) = (width.max(1), height.max(1));
    let linear: Vec<[f64; 3]> = (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let dir = equirect_uv_to_dir((x as f64 + 0.5) / width as f64, (y as f64 + 0.5) / height as f64);
            cube.sample(dir)
        })
        .collect();
    let scale = auto_scale(linear.iter().copied());
    PreviewImage { width, height, rgba: linear.iter().map(|&c| display_rgb8(c, scale)).collect() }
}

/// The normal a sphere preview shows at pixel `(x, y)`: an orthographic view down -Z of the
/// unit sphere (+X right, +Y up), or `None` outside its silhouette.
pub fn sphere_normal(x: usize, y: usize, size: usize) -> Option<DVec3> {
    let u = 2.0 * (x as f64 + 0.5) / size as f64 - 1.0;
    let v = 1.0 - 2.0 * (y as f64 + 0.5) / size as f64;
    let r2 = u * u + v * v;
    (r2 <= 1.0).then(|| DVec3::new(u, v, (1.0 - r2).sqrt()))
}

/// A white Lambertian sphere lit by SH radiance: each pixel shows the exit radiance
/// `E(n)/π` with `E` the SH irradiance (Sun 2008 eq. 2.20), auto-exposed; transparent outside.
pub fn sh_lighting_sphere(radiance: &ShRgb, size: usize) -> PreviewImage {
    let size = size.max(1);
    let irradiance = radiance.irradiance();
    let basis = ShBasis::new(irradiance.bands);
    let exit: Vec<Option<[f64; 3]>> = (0..size * size)
        .map(|i| {
            sphere_normal(i % size, i / size, size)
                .map(|n| irradiance.eval(&basis, n).map(|e| e.max(0.0) / std::f64::consts::PI))
        })
        .collect();
    let scale = auto_scale(exit.iter().flatten().copied());
    let rgba = exit.iter().map(|c| c.map_or([0, 0, 0, 0], |c| display_rgb8(c, scale))).collect();
    PreviewImage { width: size, height: size, rgba }
}

/// A point light's glow through fog: a `size²` view (60° across) straight at an isotropic
/// source 10 m away, the ray to infinity, each pixel the airlight of eq. 3.16 per channel
/// (`beta` per RGB channel) plus the attenuated source itself in the centre pixel. Fixed
/// exposure (the source's unattenuated irradiance), so denser fog shows a dimmer, wider glow.
pub fn fog_glow(
    beta: [f64; 3],
    phase: &crate::single_scattering::Phase,
    tables: &[crate::single_scattering::FTable],
    size: usize,
) -> PreviewImage {
    use crate::single_scattering::{AirlightQuery, Interpolation, airlight};
    let size = size.max(1);
    let d_sv = 10.0;
    let half_fov = 30f64.to_radians();
    let rgba = (0..size * size)
        .map(|i| {
            let (x, y) = (i % size, i / size);
            let px = (2.0 * (x as f64 + 0.5) / size as f64 - 1.0) * half_fov.tan();
            let py = (2.0 * (y as f64 + 0.5) / size as f64 - 1.0) * half_fov.tan();
            let gamma = (px * px + py * py).sqrt().atan();
            let radiance = beta.map(|b| {
                let q = AirlightQuery { beta: b, d_sv, d_vp: f64::INFINITY, gamma, i0: 1.0 };
                airlight(&q, phase, tables, Interpolation::Bilinear)
            });
            // Scaled so clear air at 10 m shows the source as mid-grey.
            display_rgb8(radiance, d_sv * d_sv * 4.0)
        })
        .collect();
    PreviewImage { width: size, height: size, rgba }
}

/// The square lights' regions over an equirectangular thumbnail of the cube map they were
/// fitted to (the environment's own frame, before rotation), auto-exposed, with the borders
/// between regions drawn in green (Xu et al. Fig. 6).
pub fn square_light_regions(
    cube: &CubeMap,
    lights: &crate::rsl::SquareLights,
    width: usize,
    height: usize,
) -> PreviewImage {
    let mut image = environment_thumbnail(cube, width, height);
    let (width, height) = (image.width, image.height);
    let n = lights.size;
    if cube.size != n || lights.labels.len() != 6 * n * n {
        return image;
    }
    let label = |x: usize, y: usize| {
        let dir = equirect_uv_to_dir((x as f64 + 0.5) / width as f64, (y as f64 + 0.5) / height as f64);
        let (face, u, v) = crate::cubemap::dir_to_face_uv(dir);
        let (tx, ty) = (((u * n as f64) as usize).min(n - 1), ((v * n as f64) as usize).min(n - 1));
        lights.labels[(face * n + ty) * n + tx]
    };
    let labels: Vec<u32> = (0..width * height).map(|i| label(i % width, i / width)).collect();
    for y in 0..height {
        for x in 0..width {
            let here = labels[y * width + x];
            let border = (x + 1 < width && labels[y * width + x + 1] != here)
                || (y + 1 < height && labels[(y + 1) * width + x] != here);
            if border {
                image.rgba[y * width + x] = [40, 230, 60, 255];
            }
        }
    }
    image
}

/// The square lights alone, on the environment sphere seen from outside along -Z (+X right, +Y
/// up): each square drawn at its centre with its solid angle (edge `√Ω` on the tangent plane;
/// its turn is arbitrary, so it is drawn aligned to a fixed up vector) and its radiance,
/// auto-exposed; transparent outside the sphere.
pub fn square_lights_sphere(lights: &crate::rsl::SquareLights, size: usize) -> PreviewImage {
    let size = size.max(1);
    let squares: Vec<(glam::DMat3, f64, [f64; 3])> = lights
        .lights
        .iter()
        .map(|l| {
            let frame = crate::rsl::ovdf::frame_towards(DVec3::from(l.direction));
            ((frame.transpose()), (l.solid_angle.sqrt() * 0.5).tan(), l.intensity)
        })
        .collect();
    let radiance: Vec<Option<[f64; 3]>> = (0..size * size)
        .map(|i| {
            sphere_normal(i % size, i / size, size).map(|d| {
                let mut sum = [0.0; 3];
                for (to_local, half, intensity) in &squares {
                    let local = *to_local * d;
                    if local.z > 0.0 && (local.x / local.z).abs() <= *half && (local.y / local.z).abs() <= *half {
                        for c in 0..3 {
                            sum[c] += intensity[c];
                        }
                    }
                }
                sum
            })
        })
        .collect();
    let scale = auto_scale(radiance.iter().flatten().copied());
    let rgba = radiance.iter().map(|c| c.map_or([0, 0, 0, 0], |c| display_rgb8(c, scale))).collect();
    PreviewImage { width: size, height: size, rgba }
}

/// The BRDF editor's normal-map preview, three `size²` panels side by side: the map (its
/// normals as colours, `n/2 + 1/2`, up to one repeat); the NDF of the map's centre texel at
/// MIP level `level`, as the density of its normals (the map's bilinear field sampled twice per
/// texel) over the hemisphere seen from above; and the effective lobe there, the BRDF averaged
/// over those normals (Sun 2008 eq. 5.4) for a viewer 30° from the normal, `f·cos θ_i` over
/// the incident hemisphere. Both plots are heat maps scaled to their peak; `level` past the top
/// shows the whole map.
pub fn normal_map_panels(
    map: &crate::normal_filtering::NormalMap,
    brdf: &crate::brdf::Brdf,
    level: usize,
    size: usize,
) -> PreviewImage {
    let size = size.max(8);
    let mut rgba = vec![[0u8; 4]; 3 * size * size];
    let mut put = |panel: usize, x: usize, y: usize, c: [u8; 4]| rgba[y * 3 * size + panel * size + x] = c;
    if map.normals.is_empty() {
        return PreviewImage { width: 3 * size, height: size, rgba };
    }
    // The map, nearest texel.
    for y in 0..size {
        for x in 0..size {
            let (mx, my) = (x * map.width / size, y * map.height / size);
            let n = map.normals[my * map.width + mx];
            let [r, g, b] = n.to_array().map(|c| ((c * 0.5 + 0.5) * 255.0).round().clamp(0.0, 255.0) as u8);
            put(0, x, y, [r, g, b, 255]);
        }
    }
    // The centre texel's block at the level, sampled twice per texel (at most 64² samples).
    let block = (1usize << level.min(24)).min(map.width.max(map.height).next_power_of_two());
    let (x0, y0) = ((map.width / 2) / block * block, (map.height / 2) / block * block);
    let side = (2 * block).min(64);
    let normals: Vec<DVec3> = (0..side * side)
        .map(|i| {
            let (sx, sy) = ((i % side) as f64 + 0.5, (i / side) as f64 + 0.5);
            let px = x0 as f64 + sx * block as f64 / side as f64;
            let py = y0 as f64 + sy * block as f64 / side as f64;
            map.sample([px / map.width as f64, py / map.height as f64])
        })
        .collect();
    let disc = |x: usize, y: usize| {
        let u = 2.0 * (x as f64 + 0.5) / size as f64 - 1.0;
        let v = 1.0 - 2.0 * (y as f64 + 0.5) / size as f64;
        (u * u + v * v <= 1.0).then(|| DVec3::new(u, v, (1.0 - u * u - v * v).max(0.0).sqrt()))
    };
    // The NDF: each normal splatted into the disc (orthographic from above), per solid angle.
    let mut density = vec![0.0f64; size * size];
    for n in &normals {
        let (x, y) = (((n.x + 1.0) * 0.5 * size as f64) as usize, ((1.0 - n.y) * 0.5 * size as f64) as usize);
        if x < size && y < size && n.z > 0.0 {
            density[y * size + x] += 1.0 / n.z.max(0.05);
        }
    }
    let wo = DVec3::new(30f64.to_radians().sin(), 0.0, 30f64.to_radians().cos());
    let lobe: Vec<f64> = (0..size * size)
        .map(|i| {
            let Some(wi) = disc(i % size, i / size) else { return 0.0 };
            let mean = normals
                .iter()
                .map(|n| {
                    let (t, b) = n.any_orthonormal_pair();
                    let local = |w: DVec3| DVec3::new(w.dot(t), w.dot(b), w.dot(*n));
                    let f = brdf.eval(local(wi), local(wo));
                    (0.2126 * f.x + 0.7152 * f.y + 0.0722 * f.z) * wi.dot(*n).max(0.0)
                })
                .sum::<f64>();
            mean / normals.len() as f64
        })
        .collect();
    for (panel, values) in [(1, &density), (2, &lobe)] {
        let peak = values.iter().copied().fold(0.0, f64::max).max(1e-300);
        for y in 0..size {
            for x in 0..size {
                let colour = match disc(x, y) {
                    Some(_) => heat(values[y * size + x] / peak),
                    None => [0, 0, 0, 0],
                };
                put(panel, x, y, colour);
            }
        }
    }
    PreviewImage { width: 3 * size, height: size, rgba }
}

/// A dark-blue → red → yellow → white ramp of `t` in `[0, 1]`.
fn heat(t: f64) -> [u8; 4] {
    let t = t.clamp(0.0, 1.0).sqrt();
    let channel = |a: f64| (a.clamp(0.0, 1.0) * 255.0).round() as u8;
    [channel(3.0 * t), channel(3.0 * t - 1.0), channel((0.35 * (1.0 - 3.0 * t)).max(3.0 * t - 2.0)), 255]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh;

    #[test]
    fn square_light_previews_show_region_borders_and_the_squares_where_they_are() {
        // A sky with one bright patch straight ahead (-Z, the thumbnail's centre and, seen
        // from +Z, the far side of the sphere) and one at +Z (the sphere's front).
        let cube = CubeMap::from_fn(16, 1, |d| if d.z > 0.95 { [40.0; 3] } else { [0.2, 0.3, 0.5] });
        let sequence =
            crate::rsl::MergeSequence::compute(&cube, &crate::engine::CancelToken::default(), &|_| {}).unwrap();
        let lights = sequence.cut(&cube, 12);
        let regions = square_light_regions(&cube, &lights, 96, 48);
        let green = regions.rgba.iter().filter(|p| **p == [40, 230, 60, 255]).count();
        assert!(green > 48, "borders between 12 regions: {green} pixels");
        // The squares themselves: a bright one facing the viewer (+Z) and a dim one behind.
        let light = |direction: [f64; 3], intensity: f64| crate::rsl::SquareLight {
            direction,
            solid_angle: 0.2,
            intensity: [intensity; 3],
            half_diagonal_texels: 1.0,
            fit_error: 0.0,
            texels: 1,
        };
        let pair = crate::rsl::SquareLights {
            size: 1,
            lights: vec![light([0.0, 0.0, 1.0], 50.0), light([0.0, 0.0, -1.0], 1.0)],
            labels: Vec::new(),
        };
        let sphere = square_lights_sphere(&pair, 65);
        let centre = sphere.rgba[32 * 65 + 32];
        let rim = sphere.rgba[32 * 65 + 3];
        assert!(centre[0] > rim[0] + 60, "the bright square faces the viewer: centre {centre:?}, rim {rim:?}");
        assert_eq!(sphere.rgba[0][3], 0, "transparent outside the sphere");
    }

    #[test]
    fn constant_environment_gives_a_uniform_thumbnail_and_sphere() {
        let cube = CubeMap::new(4, vec![[0.5, 0.5, 0.5]; 6 * 16]);
        let thumb = environment_thumbnail(&cube, 32, 16);
        assert!(thumb.rgba.iter().all(|p| p == &thumb.rgba[0]));
        // Uniform radiance L: E = πL everywhere, so every sphere pixel is equal.
        let sh = sh::project_samples(3, cube.samples());
        let sphere = sh_lighting_sphere(&sh, 24);
        let inside: Vec<_> = sphere.rgba.iter().filter(|p| p[3] == 255).collect();
        assert!(inside.len() > 24 * 24 / 2);
        assert!(inside.iter().all(|p| p[0].abs_diff(inside[0][0]) <= 1), "uniform light must shade uniformly");
    }

    #[test]
    fn sphere_is_brightest_where_the_normal_faces_the_light() {
        // A small bright cap around a direction: the brightest pixel's normal points at it.
        let light = DVec3::new(0.4, 0.7, 0.6).normalize();
        let cube = CubeMap::from_fn(16, 2, |d| if d.dot(light) > 0.95 { [10.0; 3] } else { [0.01; 3] });
        let sh = sh::project_samples(4, cube.samples());
        let size = 64;
        let sphere = sh_lighting_sphere(&sh, size);
        let (best, _) = sphere
            .rgba
            .iter()
            .enumerate()
            .filter(|(_, p)| p[3] == 255)
            .max_by_key(|(_, p)| p[1])
            .expect("sphere pixels");
        let n = sphere_normal(best % size, best / size, size).unwrap();
        assert!(n.dot(light) > 0.97, "brightest normal {n} vs light {light}");
    }

    #[test]
    fn thumbnail_places_directions_by_the_equirect_convention() {
        // Only +X is bright: it must land at u = 0.75, v = 0.5.
        let cube = CubeMap::from_fn(16, 2, |d| if d.x > 0.9 { [5.0; 3] } else { [0.0; 3] });
        let (w, h) = (64, 32);
        let thumb = environment_thumbnail(&cube, w, h);
        let (best, _) = thumb.rgba.iter().enumerate().max_by_key(|(_, p)| p[0]).unwrap();
        let (x, y) = (best % w, best / w);
        assert!((x as f64 / w as f64 - 0.75).abs() < 0.1 && (y as f64 / h as f64 - 0.5).abs() < 0.15, "{x},{y}");
    }

    #[test]
    fn fog_glow_widens_and_brightens_with_beta_then_fades() {
        use crate::single_scattering::{FTable, Phase};
        let tables = [FTable::new(0, 128)];
        let phase = Phase::isotropic();
        let size = 33;
        // Mean brightness of a ring halfway out, per β.
        let ring = |beta: f64| {
            let img = fog_glow([beta; 3], &phase, &tables, size);
            let c = size / 2;
            let r = size / 4;
            [(c + r, c), (c - r, c), (c, c + r), (c, c - r)]
                .iter()
                .map(|&(x, y)| f64::from(img.rgba[y * size + x][0]))
                .sum::<f64>()
        };
        assert_eq!(ring(0.0), 0.0, "no medium, no glow");
        assert!(ring(0.05) > ring(0.01), "more scattering, brighter halo");
        assert!(ring(3.0) < ring(0.1), "very dense fog attenuates the glow away");
        let img = fog_glow([0.05; 3], &phase, &tables, size);
        let centre = img.rgba[(size / 2) * size + size / 2][0];
        let corner = img.rgba[0][0];
        assert!(centre > corner, "the glow peaks at the source");
    }

    /// The normal-map preview: a flat map's NDF is one spot at the disc's centre, and its
    /// effective lobe is the BRDF's own (`f·cos θ_i` for a viewer 30° off the normal peaks at the
    /// mirror direction, 30° to the other side); a tilted map moves both.
    #[test]
    fn the_normal_map_preview_shows_the_ndf_and_the_effective_lobe() {
        let brdf = crate::brdf::Brdf {
            diffuse: DVec3::ZERO,
            specular: DVec3::ONE,
            f0: 1.0,
            lobe: crate::brdf::Lobe::BlinnPhong { exponent: 200.0 },
        };
        let size = 33;
        let peak_of = |image: &PreviewImage, panel: usize| {
            let value = |x: usize, y: usize| {
                let c = image.rgba[y * 3 * size + panel * size + x];
                u32::from(c[0]) + u32::from(c[1]) + u32::from(c[2])
            };
            (0..size * size).map(|i| (i % size, i / size)).max_by_key(|&(x, y)| value(x, y)).unwrap()
        };
        let flat = crate::normal_filtering::NormalMap::flat(16, 16);
        let image = normal_map_panels(&flat, &brdf, 2, size);
        assert_eq!((image.width, image.height), (3 * size, size));
        assert_eq!(peak_of(&image, 1), (16, 16), "a flat NDF is a spot at the centre");
        let (x, y) = peak_of(&image, 2);
        let u = 2.0 * (x as f64 + 0.5) / size as f64 - 1.0;
        assert!(y == 16 && (u + 30f64.to_radians().sin()).abs() < 0.08, "the mirror direction: ({x}, {y}), u {u}");
        let tilt = DVec3::new(0.3, 0.0, 1.0).normalize();
        let tilted = crate::normal_filtering::NormalMap { width: 16, height: 16, normals: vec![tilt; 256] };
        let image = normal_map_panels(&tilted, &brdf, 2, size);
        let (x, _) = peak_of(&image, 1);
        assert!(x > 16, "the NDF's spot follows the tilt toward +x: {x}");
    }
}
