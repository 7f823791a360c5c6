//! `lightloom bake` through the real binary: every exported file passes the Khronos
//! glTF-Validator (npm `gltf-validator`, run with Node) with no errors or warnings; the same
//! project gives the same bytes; a failed or cancelled bake leaves the folder as it was.

use std::path::{Path, PathBuf};
use std::process::Command;

fn lightloom() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lightloom"))
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightloom-bake-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn bake(project: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut command = lightloom();
    command.arg("bake").arg(project).arg("--out").arg(out).args(extra);
    command.output().unwrap()
}

/// The validator's Node package, installed from `tools/package.json` on first use (`.ci/run`
/// installs it up front). Fails loudly without Node or npm.
fn validator() -> PathBuf {
    static READY: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    READY
        .get_or_init(|| {
            let tools = repo().join("tools");
            if !tools.join("node_modules/gltf-validator").exists() {
                let status = Command::new("npm")
                    .args(["ci", "--no-audit", "--no-fund", "--prefix"])
                    .arg(&tools)
                    .status()
                    .expect("npm is needed to install the glTF validator: install nodejs and npm (.ci/run does)");
                assert!(status.success(), "npm ci in tools/ failed");
            }
            tools.join("validate_gltf.mjs")
        })
        .clone()
}

/// The validator's report on `file`: (errors, warnings, messages that are errors or warnings).
fn validate(file: &Path) -> (u64, u64, Vec<String>) {
    let out = Command::new("node")
        .arg(validator())
        .arg(file)
        .output()
        .expect("node is needed to run the glTF validator: install nodejs (.ci/run does)");
    assert!(out.status.success(), "validator: {}", String::from_utf8_lossy(&out.stderr));
    let reports: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let issues = &reports[0]["issues"];
    let serious = issues["messages"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["severity"].as_u64().unwrap() < 2)
        .map(|m| format!("{} at {}: {}", m["code"], m["pointer"], m["message"]))
        .collect();
    (issues["numErrors"].as_u64().unwrap(), issues["numWarnings"].as_u64().unwrap(), serious)
}

/// The default scene (sky with a sun, wavelet per-pixel mode) and the foggy street (point
/// lights, fog, SH transfer): valid glTF, and the same bytes from a second bake that computes
/// everything again.
#[test]
fn baked_scenes_pass_the_khronos_validator_and_are_deterministic() {
    let dir = temp_dir("valid");
    let street = repo().join("projects/samples/fog_street.ron");
    let default = repo().join("projects/default.ron");
    for (name, project) in [("default", default.as_path()), ("street", street.as_path())] {
        let first = dir.join(format!("{name}-1"));
        let out = bake(project, &first, &["--no-disk-cache"]);
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        let (errors, warnings, messages) = validate(&first.join("scene.glb"));
        assert_eq!((errors, warnings), (0, 0), "{name}: {messages:#?}");
        let second = dir.join(format!("{name}-2"));
        let out = bake(project, &second, &["--no-disk-cache", "-q"]);
        assert!(out.status.success());
        for file in ["scene.glb", "bake.json"] {
            assert!(
                std::fs::read(first.join(file)).unwrap() == std::fs::read(second.join(file)).unwrap(),
                "{name}: {file} differs between two bakes"
            );
        }
    }
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("street-1/bake.json")).unwrap()).unwrap();
    assert_eq!(manifest["point_lights"], 3);
}

/// A bake that fails (a missing environment file) writes nothing and says why.
#[test]
fn a_failed_bake_leaves_the_folder_as_it_was() {
    let dir = temp_dir("failed");
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    std::fs::write(out_dir.join("scene.glb"), b"previous").unwrap();
    let project = repo().join("projects/default.ron");
    let out =
        bake(&project, &out_dir, &["--no-disk-cache", "--set", "sky.source=file", "--set", "sky.file=missing.exr"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("missing.exr"), "{stderr}");
    let names: Vec<_> = std::fs::read_dir(&out_dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, ["scene.glb"]);
    assert_eq!(std::fs::read(out_dir.join("scene.glb")).unwrap(), b"previous");
}

/// Ctrl+C during the transport precompute: the bake stops, says it was cancelled, and writes
/// nothing.
#[cfg(unix)]
#[test]
fn ctrl_c_cancels_a_bake_and_writes_nothing() {
    let dir = temp_dir("cancel");
    let project = repo().join("projects/default.ron");
    let out_dir = dir.join("out");
    let child = lightloom()
        .arg("bake")
        .arg(&project)
        .arg("--out")
        .arg(&out_dir)
        .args(["--no-disk-cache", "--set", "output.mode=sh_prt", "--set", "scene.transport_rays=16384"])
        .stderr(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let started = std::time::Instant::now();
    let out = child.wait_with_output().unwrap();
    assert!(started.elapsed().as_secs() < 20, "cancelling took {:?}", started.elapsed());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("cancelled"), "{stderr}");
    assert!(!out_dir.join("scene.glb").exists());
}
