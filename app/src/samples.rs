//! The sample projects and every file they read, built into the program.
//!
//! File → Open sample, `lightloom render sample:NAME` (and every other command that reads one
//! project: the editor, eval, info, accuracy, bake) and the benchmarks that run on a sample
//! work from any folder, also from a binary installed with `cargo install --path app` and run
//! outside any checkout. Each use writes the files that are missing or differ into a folder of
//! their own (`$LIGHTLOOM_DATA_DIR/samples/<version>-<hash>`, else `$XDG_DATA_HOME/lightloom/…`,
//! else `~/.local/share/lightloom/…`), laid out as in the repository, so each project's relative
//! paths resolve there unchanged; each file is written whole or not at all.

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// Every file the samples read, as `(path in the repository, bytes)`: the projects, their
/// textures and the assets they name, with those assets' licences (listed by `build.rs`).
const FILES: &[(&str, &[u8])] = include!(concat!(env!("OUT_DIR"), "/sample_files.rs"));

/// Where the sample projects sit among [`FILES`].
const PROJECTS: &str = "projects/samples/";

/// The prefix that names a built-in sample where a project file is expected.
pub const PREFIX: &str = "sample:";

/// A built-in sample project.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Its file name without `.ron` (what `sample:NAME` names).
    pub stem: &'static str,
    /// Its project name, without the "Sample: " prefix.
    pub title: String,
}

/// The built-in samples, by title.
pub fn list() -> Vec<Sample> {
    static LIST: std::sync::OnceLock<Vec<Sample>> = std::sync::OnceLock::new();
    LIST.get_or_init(parse_list).clone()
}

fn parse_list() -> Vec<Sample> {
    let mut samples: Vec<Sample> = FILES
        .iter()
        .filter_map(|(path, bytes)| {
            let stem = path.strip_prefix(PROJECTS)?.strip_suffix(".ron")?;
            let text = std::str::from_utf8(bytes).ok()?;
            let project = lightloom_nodes::project::Project::from_ron(text, Path::new(path)).ok()?;
            let title = project.name.strip_prefix("Sample: ").unwrap_or(&project.name).to_string();
            Some(Sample { stem, title })
        })
        .collect();
    samples.sort_by(|a, b| a.title.cmp(&b.title));
    samples
}

/// `NAME` where `arg` is `sample:NAME`.
pub fn named(arg: &Path) -> Option<&str> {
    arg.to_str()?.strip_prefix(PREFIX)
}

/// The project file `arg` names: a built-in sample's (written out if need be) for
/// `sample:NAME`, else `arg` itself.
pub fn resolve(arg: &Path) -> Result<PathBuf> {
    match named(arg) {
        Some(name) => project(name),
        None => Ok(arg.to_path_buf()),
    }
}

/// The written-out project file of the sample `stem`.
pub fn project(stem: &str) -> Result<PathBuf> {
    if !FILES.iter().any(|(path, _)| *path == format!("{PROJECTS}{stem}.ron")) {
        let names: Vec<&str> = list().iter().map(|s| s.stem).collect();
        bail!("there is no built-in sample `{stem}` (the samples are {})", names.join(", "));
    }
    file(&format!("{PROJECTS}{stem}.ron"))
}

/// A file of the samples (its path in the repository), written out if need be.
pub fn file(path: &str) -> Result<PathBuf> {
    if !FILES.iter().any(|(p, _)| *p == path) {
        bail!("`{path}` is not among the samples' built-in files");
    }
    Ok(folder()?.join(path))
}

/// The folder holding the samples' files, with any file that is missing or differs written
/// out again (a few milliseconds: the files are compared, not rewritten).
pub fn folder() -> Result<PathBuf> {
    let dir = data_dir().join("samples").join(format!("{}-{:016x}", env!("CARGO_PKG_VERSION"), content_hash()));
    write_out(&dir).context("cannot write out the built-in samples")?;
    Ok(dir)
}

/// `$LIGHTLOOM_DATA_DIR`, else `$XDG_DATA_HOME/lightloom`, else `~/.local/share/lightloom`.
fn data_dir() -> PathBuf {
    crate::user_dirs::user_dir("LIGHTLOOM_DATA_DIR", "XDG_DATA_HOME", ".local/share")
}

/// A hash of every path and byte of [`FILES`]: a new build with other samples writes them
/// to a folder of their own.
fn content_hash() -> u64 {
    let mut hasher = xxhash_rust::xxh3::Xxh3::new();
    for (path, bytes) in FILES {
        hasher.update(path.as_bytes());
        hasher.update(&(bytes.len() as u64).to_le_bytes());
        hasher.update(bytes);
    }
    hasher.digest()
}

/// Writes every file under `dir` that is missing or differs, each whole or not at all (a
/// temporary file beside it, renamed over it).
fn write_out(dir: &Path) -> Result<()> {
    for (path, bytes) in FILES {
        let target = dir.join(path);
        if std::fs::read(&target).is_ok_and(|existing| existing == *bytes) {
            continue;
        }
        let parent = target.parent().expect("sample files sit in folders");
        std::fs::create_dir_all(parent).with_context(|| format!("cannot create {}", parent.display()))?;
        let mut tmp = tempfile::NamedTempFile::new_in(parent)
            .with_context(|| format!("cannot create a file in {}", parent.display()))?;
        std::io::Write::write_all(&mut tmp, bytes).with_context(|| format!("cannot write {}", target.display()))?;
        tmp.as_file().sync_all().with_context(|| format!("cannot write {}", target.display()))?;
        tmp.persist(&target).map_err(|e| e.error).with_context(|| format!("cannot write {}", target.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn repo() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
    }

    /// Every project in `projects/samples/` is built in, with every file it names, and each
    /// names only files inside the written-out folder.
    #[test]
    fn every_sample_is_built_in_with_the_files_it_reads() {
        let on_disk: Vec<String> = std::fs::read_dir(repo().join(PROJECTS))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".ron"))
            .collect();
        let built_in = list();
        assert_eq!(built_in.len(), on_disk.len(), "{on_disk:?} against {built_in:?}");
        for name in &on_disk {
            assert!(built_in.iter().any(|s| format!("{}.ron", s.stem) == *name), "{name} is not built in");
        }
        let dir = tempfile::tempdir().unwrap();
        write_out(dir.path()).unwrap();
        for sample in &built_in {
            let path = dir.path().join(format!("{PROJECTS}{}.ron", sample.stem));
            let (project, graph) = lightloom_nodes::project::Project::load(&path).unwrap();
            let missing = project.missing_assets(&graph);
            assert!(missing.is_empty(), "{}: {missing:?}", sample.stem);
            let root = dir.path().canonicalize().unwrap();
            for node in &project.nodes {
                for file in node.params.values().flat_map(|v| v.files()) {
                    let resolved = graph.project_dir.join(file).canonicalize().unwrap();
                    assert!(
                        resolved.starts_with(&root),
                        "{}: {} names {file} outside the samples",
                        sample.stem,
                        node.id
                    );
                }
            }
        }
    }

    /// Writing out again keeps what is right and mends what differs; unknown names are refused
    /// with the list of samples.
    #[test]
    fn writing_out_mends_changed_files_and_names_unknown_samples() {
        let dir = tempfile::tempdir().unwrap();
        write_out(dir.path()).unwrap();
        let project = dir.path().join(format!("{PROJECTS}engine.ron"));
        std::fs::write(&project, "edited").unwrap();
        let hdr = dir.path().join("assets/envmaps/studio.hdr");
        let before = std::fs::metadata(&hdr).unwrap().modified().unwrap();
        write_out(dir.path()).unwrap();
        assert_eq!(std::fs::read(&project).unwrap(), FILES.iter().find(|f| f.0.ends_with("engine.ron")).unwrap().1);
        assert_eq!(std::fs::metadata(&hdr).unwrap().modified().unwrap(), before, "an unchanged file is left alone");
        assert_eq!(named(Path::new("sample:engine")), Some("engine"));
        assert_eq!(resolve(Path::new("x/engine.ron")).unwrap(), Path::new("x/engine.ron"));
        let error = project_error("no_such_sample");
        assert!(
            error.contains("no_such_sample") && error.contains("engine") && error.contains("fog_street"),
            "{error}"
        );
    }

    fn project_error(stem: &str) -> String {
        format!("{:#}", project(stem).unwrap_err())
    }
}
