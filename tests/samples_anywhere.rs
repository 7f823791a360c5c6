//! The samples from a binary run outside any checkout: the `lightloom` binary copied alone into
//! an empty folder (as `cargo install --path app` leaves it in `~/.cargo/bin`) and run from
//! another empty folder, with a home of its own. It lists the built-in samples, renders each
//! with `lightloom render sample:NAME`, and the editor opens one as File → Open sample does.
//! (`cli.rs` renders each sample's project file from the checkout.)

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// An installed binary: the program alone in `bin/`, a `work/` folder to run it from and a
/// `home/`, all fresh.
struct Installed {
    _root: tempfile::TempDir,
    bin: PathBuf,
    work: PathBuf,
    home: PathBuf,
}

impl Installed {
    fn new() -> Self {
        let root = tempfile::tempdir().unwrap();
        let (bin_dir, work, home) = (root.path().join("bin"), root.path().join("work"), root.path().join("home"));
        for dir in [&bin_dir, &work, &home] {
            std::fs::create_dir_all(dir).unwrap();
        }
        let bin = bin_dir.join("lightloom");
        std::fs::copy(env!("CARGO_BIN_EXE_lightloom"), &bin).unwrap();
        Self { _root: root, bin, work, home }
    }

    /// `program` run from `work/`, with the home and none of the folders a user may set.
    fn command_of(&self, program: &Path) -> Command {
        let mut command = Command::new(program);
        command.current_dir(&self.work).env("HOME", &self.home);
        for var in ["XDG_DATA_HOME", "XDG_STATE_HOME", "XDG_CACHE_HOME", "LIGHTLOOM_DATA_DIR", "LIGHTLOOM_STATE_DIR"] {
            command.env_remove(var);
        }
        command
    }

    fn command(&self) -> Command {
        self.command_of(&self.bin)
    }

    fn run(&self, args: &[&str]) -> Output {
        let out = output(self.command().args(args));
        assert!(
            out.status.success(),
            "lightloom {args:?} failed: {}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }
}

/// The sample names `lightloom samples` lists.
fn listed(installed: &Installed) -> Vec<String> {
    let out = installed.run(&["samples"]);
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix("sample:"))
        .map(|l| l.split_whitespace().next().unwrap().to_string())
        .collect()
}

/// Mean and standard deviation of the luma of an image.
fn luma_stats(image: &image::RgbImage) -> (f64, f64) {
    let values: Vec<f64> = image
        .pixels()
        .map(|p| 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2]))
        .collect();
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64;
    (mean, var.sqrt())
}

#[test]
fn every_sample_renders_from_an_installed_binary_in_an_empty_folder() {
    let installed = Installed::new();
    let samples = listed(&installed);
    let on_disk = std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/samples"))
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "ron"))
        .count();
    assert_eq!(samples.len(), on_disk, "{samples:?}");
    // The files are written under the home's data folder, nowhere near the binary.
    let data = installed.home.join(".local/share/lightloom/samples");
    assert!(data.is_dir(), "{} holds the samples' files", data.display());
    for name in &samples {
        // Small, with few transport rays, to stay quick.
        let checkout = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../projects/samples/{name}.ron"));
        let project =
            lightloom_nodes::project::Project::from_ron(&std::fs::read_to_string(&checkout).unwrap(), &checkout)
                .unwrap();
        let scene = &project.nodes.iter().find(|n| n.kind == "Scene").unwrap().id;
        let rays = format!("{scene}.transport_rays=32");
        let png = format!("{name}.png");
        let sample = format!("sample:{name}");
        let args: [&str; 11] =
            ["render", &sample, "-o", &png, "--width", "192", "--height", "108", "--no-disk-cache", "--set", &rays];
        let out = installed.run(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("does not exist"), "{name}: {stderr}");
        let image = image::open(installed.work.join(&png)).unwrap().to_rgb8();
        assert_eq!(image.dimensions(), (192, 108), "{name}");
        let (mean, std) = luma_stats(&image);
        assert!(mean > 8.0 && std > 4.0, "{name}: the render is blank (luma mean {mean:.1}, std {std:.1})");
    }
    // Nothing was written beside the binary, and only the renders where it ran.
    assert_eq!(std::fs::read_dir(installed.bin.parent().unwrap()).unwrap().count(), 1);
    let written: Vec<_> = std::fs::read_dir(&installed.work).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(written.len(), samples.len(), "{written:?}");
    // A name that is no sample is refused with the list.
    let out = output(installed.command().args(["info", "sample:nonesuch"]));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("nonesuch") && stderr.contains(&samples[0]), "{stderr}");
}

/// The editor of an installed binary, in an empty folder, opens a copy of a sample
/// (`sample:NAME` takes the path File → Open sample does) and draws it without problems.
#[test]
fn the_installed_editor_opens_a_sample() {
    assert!(
        Command::new("xvfb-run").arg("--help").output().is_ok(),
        "xvfb-run is missing: install it with `apt-get install xvfb xauth` (.ci/run does)"
    );
    let installed = Installed::new();
    let shot = installed.home.join("editor.png");
    let out = installed
        .command_of(Path::new("xvfb-run"))
        .args(["-a", "-s", "-screen 0 1600x900x24"])
        .arg(&installed.bin)
        .arg("sample:glossy_courtyard")
        .arg("--screenshot")
        .arg(&shot)
        .arg("--no-disk-cache")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "the editor failed: {stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let line = stdout.lines().find(|l| l.starts_with("screenshot:")).expect("the editor reports its screenshot");
    assert!(line.contains("courtyard"), "the sample is open: {line}");
    let problems: Vec<&str> =
        stdout.lines().filter_map(|l| l.trim().strip_prefix("problem: ")).filter(|p| !p.starts_with("note:")).collect();
    assert!(problems.is_empty(), "{problems:?}");
    let image = image::open(&shot).unwrap().to_rgb8();
    let (_, std) = luma_stats(&image);
    assert!(std > 10.0, "the window is blank (luma std {std:.1})");
}

/// Runs `command` to its end. A binary copied a moment ago can be refused with "text file
/// busy" while another test thread's fork still holds the copy's write handle (until that child
/// execs); that passes within moments, so it is retried.
fn output(command: &mut Command) -> Output {
    for _ in 0..100 {
        match command.output() {
            Err(e) if e.kind() == std::io::ErrorKind::ExecutableFileBusy => {
                std::thread::sleep(std::time::Duration::from_millis(20))
            }
            result => return result.unwrap(),
        }
    }
    command.output().unwrap()
}
