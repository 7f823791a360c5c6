//! Command-line tests: run the real `lightloom` binary.

use std::path::{Path, PathBuf};
use std::process::Command;

fn lightloom() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lightloom"))
}

fn shared_assets() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    assert!(dir.is_dir(), "the shared assets are expected beside the checkout at {}", dir.display());
    dir
}

fn sh_json(args: &[&str]) -> serde_json::Value {
    let out = lightloom().arg("sh").args(args).arg("--json").output().expect("run lightloom");
    assert!(out.status.success(), "lightloom sh {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("valid JSON")
}

fn irradiance(report: &serde_json::Value, axis: &str) -> [f64; 3] {
    let entry = report["irradiance"].as_array().unwrap().iter().find(|e| e["axis"] == axis).unwrap();
    let rgb = entry["rgb"].as_array().unwrap();
    [0, 1, 2].map(|c| rgb[c].as_f64().unwrap())
}

fn write_hdr(path: &Path, width: u32, height: u32, f: impl Fn(u32, u32) -> [f32; 3]) {
    let pixels: Vec<image::Rgb<f32>> = (0..width * height).map(|i| image::Rgb(f(i % width, i / width))).collect();
    let file = std::fs::File::create(path).unwrap();
    image::codecs::hdr::HdrEncoder::new(file).encode(&pixels, width as usize, height as usize).unwrap();
}

#[test]
fn constant_environment_gives_pi_times_radiance_everywhere() {
    let dir = tempdir("constant");
    let path = dir.join("grey.hdr");
    write_hdr(&path, 256, 128, |_, _| [0.5, 1.0, 2.0]);
    let report = sh_json(&[path.to_str().unwrap(), "--bands", "3"]);
    let l00 = report["coefficients"][0]["rgb"][1].as_f64().unwrap();
    assert!((l00 - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-4, "L00 = {l00}");
    for axis in ["+X", "-X", "+Y", "-Y", "+Z", "-Z"] {
        let e = irradiance(&report, axis);
        for (c, radiance) in [0.5, 1.0, 2.0].iter().enumerate() {
            assert!((e[c] - std::f64::consts::PI * radiance).abs() < 1e-3, "{axis}: {e:?}");
        }
    }
}

#[test]
fn bright_upper_hemisphere_lights_plus_y() {
    // Radiance 1 above the horizon, 0 below: E(+Y) = π exactly, E(-Y) = 0, E(±X) = π/2;
    // 3-band SH gets within the known 9-coefficient error of a step function.
    let dir = tempdir("hemisphere");
    let path = dir.join("half.hdr");
    write_hdr(&path, 512, 256, |_, y| if y < 128 { [1.0; 3] } else { [0.0; 3] });
    let report = sh_json(&[path.to_str().unwrap(), "--bands", "3"]);
    let pi = std::f64::consts::PI;
    assert!((irradiance(&report, "+Y")[0] - pi).abs() < 0.1 * pi);
    assert!(irradiance(&report, "-Y")[0].abs() < 0.1 * pi);
    assert!((irradiance(&report, "+X")[0] - pi / 2.0).abs() < 1e-3);
    assert!((irradiance(&report, "-Z")[0] - pi / 2.0).abs() < 1e-3);
}

#[test]
fn real_environment_maps_agree_across_formats() {
    // The same HDRI as ZIP EXR, DWAB EXR and Radiance HDR gives the same SH within the
    // formats' quantisation.
    let envmaps = shared_assets().join("envmaps");
    let exr = sh_json(&[envmaps.join("courtyard.exr").to_str().unwrap(), "--bands", "4"]);
    let hdr = sh_json(&[envmaps.join("courtyard.hdr").to_str().unwrap(), "--bands", "4"]);
    let dwab = sh_json(&[envmaps.join("dwab/courtyard.exr").to_str().unwrap(), "--bands", "4"]);
    let coeffs = |r: &serde_json::Value| -> Vec<f64> {
        r["coefficients"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|c| (0..3).map(move |k| c["rgb"][k].as_f64().unwrap()))
            .collect()
    };
    let (a, b, c) = (coeffs(&exr), coeffs(&hdr), coeffs(&dwab));
    let scale = a[0].abs();
    for i in 0..a.len() {
        assert!((a[i] - b[i]).abs() < 0.02 * scale, "coefficient {i}: EXR {} vs HDR {}", a[i], b[i]);
        assert!((a[i] - c[i]).abs() < 0.02 * scale, "coefficient {i}: EXR {} vs DWAB {}", a[i], c[i]);
    }
    assert_eq!(exr["coefficients"].as_array().unwrap().len(), 16);
}

#[test]
fn bad_input_gives_a_clear_error_and_exit_code_two() {
    let dir = tempdir("bad");
    let broken = dir.join("broken.exr");
    std::fs::write(&broken, b"not an exr at all").unwrap();
    for (args, needle) in [
        (vec!["sh".to_string(), "/no/such/sky.hdr".to_string()], "/no/such/sky.hdr"),
        (vec!["sh".to_string(), broken.display().to_string()], "broken.exr"),
        (vec!["sh".to_string(), "--builtin-sky".to_string(), "--window".to_string(), "boxcar".to_string()], "boxcar"),
    ] {
        let out = lightloom().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    // Absurd band counts are refused by the argument parser (exit 2, names the option).
    let out = lightloom().args(["sh", "--builtin-sky", "--bands", "1000"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--bands"));
}

#[test]
fn default_job_runs_on_the_builtin_sky() {
    let out = lightloom().output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("built-in procedural sky") && text.contains("+Y"), "{text}");
}

fn tempdir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightloom-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
