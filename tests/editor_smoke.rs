//! Smoke test of the real editor window: start the binary under Xvfb on the default project,
//! wait for the first evaluation (`--screenshot` does), and check the screenshot shows the
//! node graph and a lit viewport.

use std::path::Path;
use std::process::Command;

fn rect(line: &str, name: &str) -> [u32; 4] {
    let part = line.split(&format!("{name} ")).nth(1).unwrap_or_else(|| panic!("no {name} in `{line}`"));
    let numbers: Vec<u32> = part.split([';', ' ']).next().unwrap().split(',').map(|v| v.parse().unwrap()).collect();
    [numbers[0], numbers[1], numbers[2], numbers[3]]
}

/// Pixels in `r` within 14 (per channel) of `color`.
fn count_color(image: &image::RgbaImage, r: [u32; 4], color: [u8; 3]) -> usize {
    let mut n = 0;
    for y in r[1]..r[3].min(image.height()) {
        for x in r[0]..r[2].min(image.width()) {
            let p = image.get_pixel(x, y);
            if (0..3).all(|c| p[c].abs_diff(color[c]) <= 14) {
                n += 1;
            }
        }
    }
    n
}

/// Mean and standard deviation of the luma in `r`.
fn luma_stats(image: &image::RgbaImage, r: [u32; 4]) -> (f64, f64) {
    let mut values = Vec::new();
    for y in r[1]..r[3].min(image.height()) {
        for x in r[0]..r[2].min(image.width()) {
            let p = image.get_pixel(x, y);
            values.push(0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2]));
        }
    }
    let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len().max(1) as f64;
    (mean, var.sqrt())
}

#[test]
fn editor_window_shows_graph_and_lit_viewport() {
    assert!(
        Command::new("xvfb-run").arg("--help").output().is_ok(),
        "xvfb-run is missing: install it with `apt-get install xvfb xauth` (.ci/run does)"
    );
    let dir = std::env::temp_dir().join(format!("lightloom-smoke-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shot = dir.join("editor.png");
    let output = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x900x24"])
        .arg(env!("CARGO_BIN_EXE_lightloom"))
        .arg("--screenshot")
        .arg(&shot)
        .arg("--no-disk-cache")
        .env("LIGHTLOOM_STATE_DIR", dir.join("state"))
        .output()
        .expect("run the editor under xvfb-run");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "the editor failed: {}\n{stdout}\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    let line = stdout.lines().find(|l| l.starts_with("screenshot:")).expect("the editor reports its screenshot");
    let image = image::open(Path::new(&shot)).expect("screenshot PNG").to_rgba8();
    assert!(image.width() >= 1000 && image.height() >= 600, "{}x{}", image.width(), image.height());
    let (_, whole_std) = luma_stats(&image, [0, 0, image.width(), image.height()]);
    assert!(whole_std > 10.0, "the window is blank (luma std {whole_std:.1})");

    // The graph: the default project's wires and pins in their port colours.
    let graph = rect(line, "graph");
    for (name, color) in [("environment", [230, 190, 60]), ("scene", [90, 150, 230]), ("material", [80, 190, 120])] {
        let n = count_color(&image, graph, color);
        assert!(n >= 20, "the graph shows no {name} pin or wire ({n} pixels of its colour)");
    }
    // Node previews: the environment thumbnail and SH sphere are bright, textured pixels.
    let (graph_mean, graph_std) = luma_stats(&image, graph);
    assert!(graph_std > 15.0, "the graph area is flat (mean {graph_mean:.1}, std {graph_std:.1})");

    // The viewport: a lit scene, not the dark placeholder.
    let viewport = rect(line, "viewport");
    let (mean, std) = luma_stats(&image, viewport);
    assert!(mean > 60.0 && std > 15.0, "the viewport is not lit: luma mean {mean:.1}, std {std:.1}");
    let _ = std::fs::remove_dir_all(&dir);
}
