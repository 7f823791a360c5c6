//! The repository stands alone: no file in it names a folder beside or above the checkout.
//!
//! Every text file of the checkout (ignored build outputs aside) is read; each relative path
//! that climbs (`../`) is resolved from where it is read from: a Rust file's `include_str!`/
//! `include_bytes!` from the file's folder, its other paths from the manifest folder of the
//! crate that compiles it (`CARGO_MANIFEST_DIR`, where `cargo test` also runs), any other file's
//! from its own folder. A path that ends up outside the checkout fails the test, with the file
//! and line named, as does an absolute path in a project file. A line (or the line above it)
//! that carries the marker `not-a-checkout-path` is path arithmetic on made-up folders
//! (hostile inputs, relative-path tests) and is skipped.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

fn checkout() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

/// The folders `.gitignore` anchors at the top (`/target`, …), and `.git`.
fn ignored(root: &Path) -> Vec<PathBuf> {
    let text = std::fs::read_to_string(root.join(".gitignore")).unwrap_or_default();
    let mut out: Vec<PathBuf> =
        text.lines().filter_map(|l| l.trim().strip_prefix('/')).map(|l| root.join(l.trim_end_matches('/'))).collect();
    out.push(root.join(".git"));
    out
}

/// Every file under `root` outside the ignored folders.
fn files(root: &Path) -> Vec<PathBuf> {
    let skip = ignored(root);
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if skip.contains(&path) || path.is_symlink() {
                continue;
            }
            if path.is_dir() {
                stack.push(path);
            } else {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// `a/b/../c` → `a/c`, without touching the file system.
fn normalize(path: &Path) -> PathBuf {
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

/// Each Rust file a manifest names (`path = "…"` of its targets), with the manifest's folder.
fn declared_targets(all: &[PathBuf]) -> HashMap<PathBuf, PathBuf> {
    let mut out = HashMap::new();
    for manifest in all.iter().filter(|p| p.file_name().is_some_and(|n| n == "Cargo.toml")) {
        let dir = manifest.parent().unwrap();
        for line in std::fs::read_to_string(manifest).unwrap().lines() {
            let Some(value) = line.trim().strip_prefix("path").map(str::trim).and_then(|l| l.strip_prefix('=')) else {
                continue;
            };
            let value = value.trim().trim_matches('"');
            if value.ends_with(".rs") {
                out.insert(normalize(&dir.join(value)), dir.to_path_buf());
            }
        }
    }
    out
}

/// The folder a Rust file's runtime paths are read from: its crate's manifest folder.
fn manifest_dir(file: &Path, root: &Path, targets: &HashMap<PathBuf, PathBuf>) -> PathBuf {
    if let Some(dir) = targets.get(file) {
        return dir.clone();
    }
    let mut dir = file.parent().unwrap();
    while dir != root && !dir.join("Cargo.toml").is_file() {
        dir = dir.parent().unwrap();
    }
    dir.to_path_buf()
}

/// The paths in `text` that start by climbing, with their byte offsets.
fn climbing_paths(text: &str) -> Vec<(usize, &str)> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(found) = text[i..].find("../") {
        let start = i + found;
        if start > 0 && bytes[start - 1] == b'.' {
            i = start + 3;
            continue;
        }
        let mut end = start;
        while text[end..].starts_with("../") {
            end += 3;
        }
        while end < bytes.len() && (bytes[end].is_ascii_alphanumeric() || b"_-./".contains(&bytes[end])) {
            end += 1;
        }
        out.push((start, &text[start..end]));
        i = end;
    }
    out
}

/// Whether the text just before `start` opens an `include_str!`/`include_bytes!`.
fn in_include(text: &str, start: usize) -> bool {
    let before = text[..start].trim_end_matches('"').trim_end();
    before.ends_with("include_str!(") || before.ends_with("include_bytes!(")
}

#[test]
fn no_file_names_a_path_outside_the_checkout() {
    let root = checkout();
    let all = files(&root);
    assert!(all.len() > 100, "{} files under {}", all.len(), root.display());
    let targets = declared_targets(&all);
    let beside = format!("{}/shared", "..");
    let mut found = Vec::new();
    for file in &all {
        let Ok(bytes) = std::fs::read(file) else { continue };
        if bytes.iter().take(8192).any(|b| *b == 0) {
            continue;
        }
        let text = String::from_utf8_lossy(&bytes);
        let lines: Vec<&str> = text.lines().collect();
        let line_of = |offset: usize| text[..offset].matches('\n').count();
        let on_purpose = |line: usize| {
            lines.get(line).is_some_and(|l| l.contains("not-a-checkout-path"))
                || (line > 0 && lines[line - 1].contains("not-a-checkout-path"))
        };
        let name = file.strip_prefix(&root).unwrap().display().to_string();
        for (offset, _) in text.match_indices(&beside) {
            if !on_purpose(line_of(offset)) {
                found.push(format!("{name}:{}: names {beside}", line_of(offset) + 1));
            }
        }
        // Projects name their files relative to themselves, never by an absolute path.
        if file.extension().is_some_and(|e| e == "ron") {
            for needle in [r#"Path("/"#, r#"file: "/"#] {
                for (offset, _) in text.match_indices(needle) {
                    if !on_purpose(line_of(offset)) {
                        found.push(format!("{name}:{}: an absolute path", line_of(offset) + 1));
                    }
                }
            }
        }
        let rust = file.extension().is_some_and(|e| e == "rs");
        for (offset, path) in climbing_paths(&text) {
            let base = if rust && !in_include(&text, offset) {
                manifest_dir(file, &root, &targets)
            } else {
                file.parent().unwrap().to_path_buf()
            };
            let resolved = normalize(&base.join(path));
            if !resolved.starts_with(&root) && !on_purpose(line_of(offset)) {
                found.push(format!(
                    "{name}:{}: {path} leads to {} (read from {})",
                    line_of(offset) + 1,
                    resolved.display(),
                    base.display()
                ));
            }
        }
    }
    assert!(found.is_empty(), "paths outside the checkout {}:\n{}", root.display(), found.join("\n"));
}

/// The program reads nothing from where it was built: outside tests, `CARGO_MANIFEST_DIR`
/// appears only in `include_str!`/`include_bytes!`, which copy the file into the binary (a
/// path made from it at run time works in a checkout and nowhere else, so a test run from the
/// checkout could not tell).
#[test]
fn the_program_reads_nothing_from_its_build_folder() {
    let root = checkout();
    let mut found = Vec::new();
    for file in files(&root) {
        let name = file.strip_prefix(&root).unwrap().display().to_string();
        let product = ["app/src/", "nodes/src/", "render/src/"].iter().any(|p| name.starts_with(p))
            && file.extension().is_some_and(|e| e == "rs")
            && !name.contains("/tests/")
            && !name.contains("ui_tests")
            && !name.ends_with("tests.rs");
        if !product {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        let shipped = text.split("#[cfg(test)]").next().unwrap();
        for (n, line) in shipped.lines().enumerate() {
            if line.contains("CARGO_MANIFEST_DIR") && !line.contains("include_bytes!") && !line.contains("include_str!")
            {
                found.push(format!("{name}:{}: {}", n + 1, line.trim()));
            }
        }
    }
    assert!(found.is_empty(), "build-time paths read at run time:\n{}", found.join("\n"));
}

/// The scan itself: a climbing path is found and resolved as the files use it.
#[test]
fn the_scan_resolves_paths_as_they_are_read() {
    let text = r#"a "../../x/y.hdr" b include_str!("../../../shaders/c.wgsl") ..../z"#; // not-a-checkout-path
    let paths: Vec<&str> = climbing_paths(text).into_iter().map(|(_, p)| p).collect();
    assert_eq!(paths, ["../../x/y.hdr", "../../../shaders/c.wgsl"]); // not-a-checkout-path
    let (offset, _) = climbing_paths(text)[1];
    assert!(in_include(text, offset) && !in_include(text, climbing_paths(text)[0].0));
    assert_eq!(normalize(Path::new("/r/app/../../elsewhere/a")), Path::new("/elsewhere/a")); // not-a-checkout-path
    let root = checkout();
    let targets = declared_targets(&files(&root));
    assert_eq!(manifest_dir(&root.join("tests/cli.rs"), &root, &targets), root.join("app"));
    assert_eq!(manifest_dir(&root.join("nodes/src/sh/mod.rs"), &root, &targets), root.join("nodes"));
}
