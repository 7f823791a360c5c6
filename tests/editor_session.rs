//! The artist's session on the real editor under Xvfb, driven by xdotool: open a glTF model
//! under an HDRI (shadows and gloss), orbit the view with the middle mouse button, save with
//! Ctrl+S, quit; reopen the saved project, and check that the CLI render of it matches what
//! the editor's viewport shows inside its render frame.

use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `x0,y0,x1,y1` after `key` in a status or screenshot line.
fn rect_after(line: &str, key: &str) -> [u32; 4] {
    let part = line.split(key).nth(1).unwrap_or_else(|| panic!("no {key} in `{line}`"));
    let v: Vec<u32> = part.split([' ', ';']).next().unwrap().split(',').map(|v| v.parse().unwrap()).collect();
    [v[0], v[1], v[2], v[3]]
}

/// Mean sRGB of each cell of a 16×9 grid over `r` of `image`.
fn cells(image: &image::RgbImage, r: [u32; 4]) -> Vec<[f64; 3]> {
    let (cols, rows) = (16u32, 9u32);
    let mut out = Vec::new();
    for cy in 0..rows {
        for cx in 0..cols {
            let (x0, x1) = (r[0] + (r[2] - r[0]) * cx / cols, r[0] + (r[2] - r[0]) * (cx + 1) / cols);
            let (y0, y1) = (r[1] + (r[3] - r[1]) * cy / rows, r[1] + (r[3] - r[1]) * (cy + 1) / rows);
            let mut sum = [0.0; 3];
            let mut n: f64 = 0.0;
            for y in y0..y1 {
                for x in x0..x1 {
                    let p = image.get_pixel(x, y);
                    for c in 0..3 {
                        sum[c] += f64::from(p[c]);
                    }
                    n += 1.0;
                }
            }
            out.push(sum.map(|s| s / n.max(1.0)));
        }
    }
    out
}

#[test]
fn an_artists_session_ends_with_a_cli_render_matching_the_viewport() {
    for tool in ["xvfb-run", "xdotool"] {
        assert!(
            Command::new("which").arg(tool).output().is_ok_and(|o| o.status.success()),
            "{tool} is missing: install it with `apt-get install xvfb xauth xdotool` (.ci/run does)"
        );
    }
    let dir = std::env::temp_dir().join(format!("lightloom-session-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // The engine sample, saved where the artist keeps it (its asset paths rebased).
    let sample = workspace().join("projects/samples/engine.ron");
    let text = std::fs::read_to_string(&sample).unwrap();
    let mut project = lightloom_nodes::project::Project::from_ron(&text, &sample).unwrap();
    project.rebase_paths(sample.parent().unwrap(), &dir);
    let original_camera = project.camera(None).unwrap();
    let path = dir.join("session.ron");
    project.save(&path).unwrap();
    let (cache, status) = (dir.join("cache"), dir.join("status.txt"));

    let script = r#"
        set -u
        "$LL" "$PROJECT" --cache-dir "$CACHE" --status-file "$STATUS" --frame-stats > "$DIR/editor.log" 2>&1 &
        pid=$!
        wait_for() {
            for _ in $(seq 1 960); do
                grep -q -- "$1" "$STATUS" 2>/dev/null && return 0
                kill -0 $pid 2>/dev/null || { echo "the editor exited"; cat "$DIR/editor.log"; exit 1; }
                sleep 0.25
            done
            echo "timed out waiting for '$1'"; kill $pid; exit 1
        }
        wait_for "settled"
        line=$(grep settled "$STATUS" | tail -1)
        vp=${line##*viewport=}; vp=${vp%% *}
        IFS=, read -r x0 y0 x1 y1 <<< "$vp"
        cx=$(( (x0 + x1) / 2 )); cy=$(( (y0 + y1) / 2 ))
        # No window manager under Xvfb: give the window the keyboard focus.
        wid=$(xdotool search --name "Lightloom" | head -1)
        xdotool windowfocus --sync "$wid"
        xdotool mousemove "$cx" "$cy"; sleep 0.5
        xdotool mousedown 2
        for _ in $(seq 1 12); do xdotool mousemove_relative -- 10 -3; sleep 0.05; done
        xdotool mouseup 2
        sleep 1
        xdotool key ctrl+s
        wait_for "^saved "
        kill $pid; wait $pid 2>/dev/null
        exit 0
    "#;
    let run = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x900x24", "bash", "-c", script])
        .env("LL", env!("CARGO_BIN_EXE_lightloom"))
        .env("PROJECT", &path)
        .env("CACHE", &cache)
        .env("STATUS", &status)
        .env("DIR", &dir)
        .env("LIGHTLOOM_STATE_DIR", dir.join("state"))
        .output()
        .expect("run the session under xvfb-run");
    let log = std::fs::read_to_string(&status).unwrap_or_default();
    assert!(
        run.status.success(),
        "the session failed:\n{}\n{}\nstatus:\n{log}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    eprintln!("session status lines:\n{log}");

    // The orbit reached the saved project as its view.
    let text = std::fs::read_to_string(&path).unwrap();
    let saved = lightloom_nodes::project::Project::from_ron(&text, &path).unwrap();
    let view = saved.view.clone().expect("the saved project has the editor's view");
    let moved = (0..3).map(|i| (view.position[i] - original_camera.position[i]).abs()).fold(0.0, f64::max);
    assert!(moved > 0.05, "the middle-drag orbit moved the view: {:?} → {:?}", original_camera.position, view.position);

    // Reopen: the editor's first settled frame, in a screenshot.
    let shot = dir.join("reopened.png");
    let reopened = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x900x24"])
        .arg(env!("CARGO_BIN_EXE_lightloom"))
        .arg(&path)
        .args(["--cache-dir", cache.to_str().unwrap(), "--screenshot", shot.to_str().unwrap()])
        .env("LIGHTLOOM_STATE_DIR", dir.join("state"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&reopened.stdout);
    assert!(reopened.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&reopened.stderr));
    let line = stdout.lines().find(|l| l.starts_with("screenshot:")).expect("a screenshot line");
    let frame = rect_after(line, "frame ");
    let shown = cells(&image::open(&shot).unwrap().to_rgb8(), [frame[0] + 1, frame[1] + 1, frame[2] - 1, frame[3] - 1]);

    // The CLI render of the saved project.
    let png = dir.join("cli.png");
    let render = Command::new(env!("CARGO_BIN_EXE_lightloom"))
        .args(["render", path.to_str().unwrap(), "-o", png.to_str().unwrap()])
        .args(["--cache-dir", cache.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap();
    assert!(render.status.success(), "{}", String::from_utf8_lossy(&render.stderr));
    let cli = image::open(&png).unwrap().to_rgb8();
    let rendered = cells(&cli, [0, 0, cli.width(), cli.height()]);
    let diffs: Vec<f64> =
        shown.iter().zip(&rendered).flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs())).collect();
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let worst = diffs.iter().cloned().fold(0.0, f64::max);
    eprintln!("reopened viewport vs CLI render: mean cell difference {mean:.2}, worst {worst:.1} (sRGB levels)");
    assert!(
        mean < 3.0 && worst < 24.0,
        "the reopened viewport and the CLI render differ: mean {mean:.2}, worst {worst:.1}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
