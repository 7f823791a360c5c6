//! The spot light with a photometric profile, through the real binary: the floor under it is
//! lit as the inverse-square and cosine laws say from the candela table in its `.ies` file
//! (read here with a few lines of our own, not the program's reader), both in the viewport's
//! image and in the Monte Carlo reference's.

use std::path::{Path, PathBuf};
use std::process::Command;

fn lightloom() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lightloom"))
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The vertical angles and candela of a one-plane (axially symmetric) type C file.
fn one_plane_candela(path: &Path) -> (Vec<f64>, Vec<f64>) {
    let text = std::fs::read_to_string(path).unwrap();
    let after_tilt = text.split("TILT=NONE").nth(1).expect("a TILT=NONE file");
    let numbers: Vec<f64> = after_tilt.split_whitespace().map(|t| t.parse().unwrap()).collect();
    let (vertical, horizontal) = (numbers[3] as usize, numbers[4] as usize);
    assert_eq!(horizontal, 1, "one plane");
    let multiplier = numbers[2] * numbers[10];
    let angles = numbers[13..13 + vertical].to_vec();
    let candela = numbers[14 + vertical..14 + 2 * vertical].iter().map(|c| c * multiplier).collect();
    (angles, candela)
}

fn interpolate(angles: &[f64], values: &[f64], x: f64) -> f64 {
    if x > *angles.last().unwrap() {
        return 0.0;
    }
    let i = angles.iter().position(|&a| a > x).unwrap_or(angles.len() - 1).max(1);
    let t = (x - angles[i - 1]) / (angles[i] - angles[i - 1]);
    values[i - 1] * (1.0 - t) + values[i] * t
}

const SIZE: usize = 96;
const HEIGHT: f64 = 2.0;
const PEAK: f64 = 10.0;

/// A white Lambert floor seen from straight above, lit only by a spot 2 m over it pointing
/// down, with the file's profile and no cone; `view` is `approximation` or `reference`.
fn render(dir: &Path, view: &str) -> Vec<[f32; 3]> {
    render_spot(dir, view, "downlight_30.ies", [0.0, -1.0, 0.0], 0.0)
}

/// The same floor under a spot with profile `ies`, aimed along `direction` and spun `spin`°.
fn render_spot(dir: &Path, view: &str, ies: &str, direction: [f64; 3], spin: f64) -> Vec<[f32; 3]> {
    let ies = repo().join("assets/ies").join(ies);
    let [dx, dy, dz] = direction;
    let project = format!(
        r#"(
        version: 4,
        cameras: [(name: "c", position: (0.0, 5.0, 0.0), target: (0.0, 0.0, 0.0), fov_y_deg: 70.0)],
        render: (width: {SIZE}, height: {SIZE}),
        nodes: [
            (id: "scene", kind: "Scene", params: {{
                "objects": Objects([(name: "floor", shape: Plane(size: 12.0), color: (1.0, 1.0, 1.0))]),
                "tessellation": Int(8),
            }}),
            (id: "spot", kind: "SpotLight", params: {{
                "position": Vec3((0.0, {HEIGHT}, 0.0)), "direction": Vec3(({dx}, {dy}, {dz})), "cone": Float(180.0),
                "spin": Float({spin}),
                "profile": Path("{}"), "intensity": Color(({PEAK}, {PEAK}, {PEAK})),
            }}),
            (id: "white", kind: "BrdfEditor", params: {{"albedo": Color((1.0, 1.0, 1.0))}}),
            (id: "out", kind: "Output", params: {{
                "mode": Choice("sh_irradiance"), "view": Choice("{view}"), "reference_samples": Int(16),
                "tonemap": Choice("linear"),
            }}),
        ],
        links: [
            (from: ("scene", "scene"), to: ("out", "scene")),
            (from: ("spot", "lights"), to: ("out", "lights")),
            (from: ("white", "material"), to: ("out", "material")),
        ],
    )"#,
        ies.display()
    );
    let name = format!("spot-{view}-{}", ies.file_stem().unwrap().to_string_lossy());
    let path = dir.join(format!("{name}.ron"));
    std::fs::write(&path, project).unwrap();
    let exr = dir.join(format!("{name}.exr"));
    let out = lightloom()
        .args(["render", path.to_str().unwrap(), "-o", exr.to_str().unwrap(), "--no-disk-cache", "-q"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let image = image::open(&exr).unwrap().into_rgb32f();
    assert_eq!(image.dimensions(), (SIZE as u32, SIZE as u32));
    image.pixels().map(|p| [p[0], p[1], p[2]]).collect()
}

/// Radiance of the floor at each pixel's centre: `albedo/π · I(γ) cos γ / d²`, `I` the file's
/// candela scaled so its peak is [`PEAK`] W/sr.
fn expected() -> Vec<f64> {
    let (angles, candela) = one_plane_candela(&repo().join("assets/ies/downlight_30.ies"));
    let peak = candela.iter().cloned().fold(0.0, f64::max);
    let tan = (70f64.to_radians() / 2.0).tan();
    let mut out = Vec::new();
    for y in 0..SIZE {
        for x in 0..SIZE {
            // Looking straight down, right is +X and up is −Z (the program's camera basis).
            let ndc = [2.0 * (x as f64 + 0.5) / SIZE as f64 - 1.0, 1.0 - 2.0 * (y as f64 + 0.5) / SIZE as f64];
            let point = [ndc[0] * tan * 5.0, -ndc[1] * tan * 5.0];
            let d2 = point[0] * point[0] + point[1] * point[1] + HEIGHT * HEIGHT;
            let cos = HEIGHT / d2.sqrt();
            let gamma = cos.acos().to_degrees();
            let intensity = PEAK * interpolate(&angles, &candela, gamma) / peak;
            out.push(intensity * cos / d2 / std::f64::consts::PI);
        }
    }
    out
}

/// Relative RMSE and relative mean difference over the lit floor (where the truth is over 2%
/// of its peak).
fn error(image: &[[f32; 3]], truth: &[f64]) -> (f64, f64) {
    let top = truth.iter().cloned().fold(0.0, f64::max);
    let (mut sq, mut sum_truth, mut sum_image, mut sq_truth) = (0.0, 0.0, 0.0, 0.0);
    for (p, t) in image.iter().zip(truth).filter(|(_, t)| **t > 0.02 * top) {
        let v = f64::from(p[1]);
        sq += (v - t) * (v - t);
        sq_truth += t * t;
        sum_truth += t;
        sum_image += v;
    }
    ((sq / sq_truth).sqrt(), sum_image / sum_truth - 1.0)
}

#[test]
fn a_spot_light_lights_the_floor_as_its_candela_table_says() {
    let dir = std::env::temp_dir().join(format!("lightloom-spot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let truth = expected();
    let viewport = render(&dir, "approximation");
    let reference = render(&dir, "reference");
    let (rmse, bias) = error(&viewport, &truth);
    let (ref_rmse, ref_bias) = error(&reference, &truth);
    println!(
        "spot light on a floor, against the inverse-square and cosine laws from the .ies table: viewport \
         {:.2}% relative RMSE ({:+.2}% mean), Monte Carlo reference {:.2}% ({:+.2}%)",
        rmse * 100.0,
        bias * 100.0,
        ref_rmse * 100.0,
        ref_bias * 100.0
    );
    assert!(rmse < 0.03 && bias.abs() < 0.01, "viewport: {rmse:.4} RMSE, {bias:+.4} mean");
    assert!(ref_rmse < 0.03 && ref_bias.abs() < 0.01, "reference: {ref_rmse:.4} RMSE, {ref_bias:+.4} mean");
    // The light is not isotropic: straight under it the floor is lit by the peak, 40° out by a
    // tiny fraction (the file falls from 7400 to 90 cd).
    let centre = truth[SIZE / 2 * SIZE + SIZE / 2];
    assert!(f64::from(viewport[SIZE / 2 * SIZE + SIZE / 2][1]) > 0.9 * centre);
}

/// A bad `.ies` file stops the spot light's evaluation with a message naming the file and the
/// problem; the rest of the project still renders.
#[test]
fn a_bad_ies_file_is_named_with_its_problem() {
    let dir = std::env::temp_dir().join(format!("lightloom-spot-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("broken.ies"),
        "IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 3 1 2 2 0 0 0\n1 1 1\n0 45 90\n0\n1 1 1\n",
    )
    .unwrap();
    let project = r#"(
        version: 4,
        cameras: [(name: "c", position: (0.0, 3.0, 3.0), target: (0.0, 0.0, 0.0), fov_y_deg: 50.0)],
        render: (width: 32, height: 32),
        nodes: [
            (id: "scene", kind: "Scene"),
            (id: "spot", kind: "SpotLight", params: {"profile": Path("broken.ies")}),
            (id: "out", kind: "Output"),
        ],
        links: [
            (from: ("scene", "scene"), to: ("out", "scene")),
            (from: ("spot", "lights"), to: ("out", "lights")),
        ],
    )"#;
    let path = dir.join("bad.ron");
    std::fs::write(&path, project).unwrap();
    let out = lightloom().args(["eval", path.to_str().unwrap(), "--no-disk-cache"]).output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("broken.ies") && text.contains("type B"), "{text}");
}

/// An asymmetric profile (the wall pack: 21 planes), aimed off the vertical and spun: the
/// viewport's shader reads the profile's table as the reference's Rust lookup does, every
/// plane where it belongs.
#[test]
fn the_viewport_reads_an_asymmetric_profile_as_the_reference_does() {
    let dir = std::env::temp_dir().join(format!("lightloom-spot-wall-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let direction = [0.35, -1.0, 0.2];
    let viewport = render_spot(&dir, "approximation", "wall_pack.ies", direction, 40.0);
    let reference = render_spot(&dir, "reference", "wall_pack.ies", direction, 40.0);
    let truth: Vec<f64> = reference.iter().map(|p| f64::from(p[1])).collect();
    let (rmse, bias) = error(&viewport, &truth);
    // And the pattern is not symmetric: mirrored about the image's centre, it differs.
    let mirrored: Vec<[f32; 3]> = (0..SIZE * SIZE).map(|i| viewport[SIZE * SIZE - 1 - i]).collect();
    let (asymmetry, _) = error(&mirrored, &truth);
    println!(
        "wall pack, aimed and spun: viewport against the reference {:.2}% relative RMSE ({:+.2}% mean); the \
         pattern turned half a turn differs by {:.0}%",
        rmse * 100.0,
        bias * 100.0,
        asymmetry * 100.0
    );
    assert!(rmse < 0.03 && bias.abs() < 0.01, "viewport against the reference: {rmse:.4} RMSE, {bias:+.4} mean");
    assert!(asymmetry > 0.1, "the profile's planes differ: {asymmetry:.3}");
}
