//! Lists the files the built-in samples read (`src/samples.rs`): every project (`.ron`) under
//! `projects/samples/`, every file a project names by a relative
//! path (`Path("…")`, `file: "…"`), and the licence files (`LICENSE*`, `COPYRIGHT*`) beside each
//! named asset and in the folders above it up to `assets/`. A new sample is a project file and
//! its assets: no code lists it.

use std::collections::BTreeSet;
use std::path::{Component, Path, PathBuf};

fn main() {
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let root = manifest.parent().expect("the app crate sits in the workspace").to_path_buf();
    let samples = root.join("projects/samples");
    println!("cargo:rerun-if-changed={}", samples.display());
    let mut files = BTreeSet::new();
    let mut folders = vec![samples.clone()];
    while let Some(folder) = folders.pop() {
        println!("cargo:rerun-if-changed={}", folder.display());
        for entry in std::fs::read_dir(&folder).unwrap_or_else(|e| panic!("{}: {e}", folder.display())) {
            let path = entry.expect("a readable folder").path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|e| e == "ron") {
                files.insert(path);
            }
        }
    }
    let projects: Vec<PathBuf> = files.iter().cloned().collect();
    for project in projects {
        let text = std::fs::read_to_string(&project).unwrap_or_else(|e| panic!("{}: {e}", project.display()));
        let dir = project.parent().unwrap();
        for named in quoted_paths(&text) {
            let path = normalise(&dir.join(named));
            assert!(path.is_file(), "{} names {named}, which is not a file", project.display());
            assert!(path.starts_with(&root), "{} names {named}, outside the repository", project.display());
            let mut folder = path.parent();
            while let Some(f) = folder.filter(|f| f.starts_with(root.join("assets"))) {
                for entry in std::fs::read_dir(f).into_iter().flatten().flatten() {
                    let name = entry.file_name().to_string_lossy().to_uppercase();
                    if entry.path().is_file() && (name.starts_with("LICENSE") || name.starts_with("COPYRIGHT")) {
                        files.insert(entry.path());
                    }
                }
                folder = f.parent();
            }
            files.insert(path);
        }
    }
    let mut out = String::from("&[\n");
    for file in &files {
        println!("cargo:rerun-if-changed={}", file.display());
        let relative = file.strip_prefix(&root).unwrap().to_str().expect("UTF-8 file names").replace('\\', "/");
        out.push_str(&format!("    ({relative:?}, include_bytes!({:?}).as_slice()),\n", file.display().to_string()));
    }
    out.push_str("]\n");
    let target = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR")).join("sample_files.rs");
    std::fs::write(&target, out).unwrap_or_else(|e| panic!("{}: {e}", target.display()));
}

/// The relative paths a project names: `Path("…")` parameters and `file: "…"` fields.
fn quoted_paths(text: &str) -> Vec<&str> {
    let mut out = Vec::new();
    for opener in ["Path(\"", "file: \""] {
        for (at, _) in text.match_indices(opener) {
            let rest = &text[at + opener.len()..];
            if let Some(end) = rest.find('"')
                && end > 0
            {
                out.push(&rest[..end]);
            }
        }
    }
    out
}

/// `path` with `.` and `..` resolved lexically.
fn normalise(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}
