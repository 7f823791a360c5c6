//! The wavelet modes' relight, which runs as a GPU compute kernel or as its CPU twin, through
//! the real binary.

use std::path::PathBuf;
use std::process::Command;

fn lightloom() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lightloom"))
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Renders the glossy courtyard (wavelet_pixel: per-vertex and per-texel products, a GGX and a
/// Blinn-Phong lobe) at `rotation` with the relight on `side`, as linear radiance.
fn render(side: &str, rotation: f64) -> image::Rgb32FImage {
    let dir = std::env::temp_dir().join(format!("lightloom-relight-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("{side}-{rotation}.exr"));
    let project = repo().join("projects/samples/glossy_courtyard.ron");
    let status = lightloom()
        .env("LIGHTLOOM_RELIGHT", side)
        .args(["render", project.to_str().unwrap(), "-o", out.to_str().unwrap(), "-q"])
        .args(["--width", "320", "--height", "180", "--no-disk-cache"])
        .args(["--set", &format!("courtyard.rotation={rotation},0,0")])
        .status()
        .unwrap();
    assert!(status.success());
    image::open(&out).unwrap().into_rgb32f()
}

fn relative_rmse(a: &image::Rgb32FImage, b: &image::Rgb32FImage) -> f64 {
    let (mut diff, mut norm) = (0.0f64, 0.0f64);
    for (p, q) in a.pixels().zip(b.pixels()) {
        for k in 0..3 {
            diff += f64::from(p[k] - q[k]).powi(2);
            norm += f64::from(q[k]).powi(2);
        }
    }
    (diff / norm).sqrt()
}

/// The same frame whichever side relights: the compute kernel (on lavapipe here) and the CPU
/// twin agree to 0.5% relative RMSE, while turning the environment by 40° changes the image
/// by far more, so the comparison can tell.
#[test]
fn the_gpu_relight_draws_what_the_cpu_relight_draws() {
    let cpu = render("cpu", 30.0);
    let gpu = render("gpu", 30.0);
    let error = relative_rmse(&gpu, &cpu);
    assert!(error < 0.005, "kernel against twin: relative RMSE {error}");
    let turned = relative_rmse(&render("cpu", 70.0), &cpu);
    assert!(turned > 20.0 * error.max(1e-4), "turning the sky changed the image by only {turned}");
    eprintln!("kernel against twin {error:.5}, turned sky {turned:.3}");
}
