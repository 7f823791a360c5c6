//! The open project and its edit history: undo/redo of every edit, unsaved-changes tracking,
//! atomic saves, autosave to a recovery file, and recent files.

use anyhow::{Context as _, Result};
use lightloom_nodes::project::Project;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How many edits undo remembers.
const UNDO_LIMIT: usize = 500;

struct HistoryEntry {
    label: String,
    before: Project,
    /// Consecutive edits with the same key merge (one slider drag is one undo step).
    merge_key: Option<String>,
}

/// A project being edited.
pub struct Document {
    pub project: Project,
    /// Where it is saved; `None` for a new or built-in project.
    pub path: Option<PathBuf>,
    /// Bumped on every change (edits, undo, redo, load).
    revision: u64,
    saved: Project,
    undo: Vec<HistoryEntry>,
    redo: Vec<HistoryEntry>,
    /// While open, edits with the same merge key extend the last undo step.
    merge_open: bool,
    autosaved_revision: u64,
    last_autosave: Instant,
}

impl Document {
    pub fn new(project: Project, path: Option<PathBuf>) -> Self {
        Self {
            saved: project.clone(),
            project,
            path,
            revision: 1,
            undo: Vec::new(),
            redo: Vec::new(),
            merge_open: false,
            autosaved_revision: 1,
            last_autosave: Instant::now(),
        }
    }

    /// Loads a project file (RON, any supported version).
    pub fn open(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let project = Project::from_ron(&text, path)?;
        Ok(Self::new(project, Some(path.to_path_buf())))
    }

    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Unsaved changes?
    pub fn is_dirty(&self) -> bool {
        self.project != self.saved
    }

    /// Relative asset paths resolve against the project's folder.
    pub fn project_dir(&self) -> PathBuf {
        self.path
            .as_ref()
            .and_then(|p| p.parent())
            .filter(|p| !p.as_os_str().is_empty())
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
    }

    /// "name — path*" for the window title.
    pub fn title(&self) -> String {
        let name = if self.project.name.is_empty() { "untitled" } else { self.project.name.as_str() };
        let place = self.path.as_ref().map_or("not saved".to_string(), |p| p.display().to_string());
        format!("{}{name} ({place}) — Lightloom", if self.is_dirty() { "● " } else { "" })
    }

    /// Applies an edit as one undo step. The edit returns `Err` to refuse (nothing changes);
    /// an edit that changes nothing records nothing.
    pub fn edit<T>(
        &mut self,
        label: impl Into<String>,
        merge_key: Option<&str>,
        f: impl FnOnce(&mut Project) -> Result<T, String>,
    ) -> Result<T, String> {
        let before = self.project.clone();
        let out = match f(&mut self.project) {
            Ok(out) => out,
            Err(e) => {
                self.project = before;
                return Err(e);
            }
        };
        if self.project == before {
            return Ok(out);
        }
        let merges = self.merge_open
            && merge_key.is_some()
            && self.undo.last().is_some_and(|last| last.merge_key.as_deref() == merge_key);
        if !merges {
            self.undo.push(HistoryEntry { label: label.into(), before, merge_key: merge_key.map(String::from) });
            if self.undo.len() > UNDO_LIMIT {
                self.undo.remove(0);
            }
        }
        self.merge_open = merge_key.is_some();
        self.redo.clear();
        self.revision += 1;
        Ok(out)
    }

    /// Ends the current merge run (the pointer was released): the next edit is a new step.
    pub fn seal(&mut self) {
        self.merge_open = false;
    }

    pub fn undo_label(&self) -> Option<&str> {
        self.undo.last().map(|e| e.label.as_str())
    }

    pub fn redo_label(&self) -> Option<&str> {
        self.redo.last().map(|e| e.label.as_str())
    }

    pub fn undo(&mut self) -> bool {
        let Some(entry) = self.undo.pop() else { return false };
        let after = std::mem::replace(&mut self.project, entry.before);
        self.redo.push(HistoryEntry { label: entry.label, before: after, merge_key: None });
        self.merge_open = false;
        self.revision += 1;
        true
    }

    pub fn redo(&mut self) -> bool {
        let Some(entry) = self.redo.pop() else { return false };
        let before = std::mem::replace(&mut self.project, entry.before);
        self.undo.push(HistoryEntry { label: entry.label, before, merge_key: None });
        self.merge_open = false;
        self.revision += 1;
        true
    }

    /// Saves atomically to `path` (keeping the previous file as `.bak`), makes it the document's
    /// path and clears its recovery file. File parameters keep naming the same files, relative
    /// to the new folder where that is short.
    pub fn save_as(&mut self, path: &Path) -> Result<()> {
        let old_recovery = recovery_path(self.path.as_deref());
        let mut project = self.project.clone();
        let (old_dir, new_dir) =
            (self.project_dir(), path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new(".")));
        project.rebase_paths(&old_dir, new_dir);
        project.save(path)?;
        self.project = project;
        // Undo and redo restore states whose relative names must resolve from here too.
        for entry in self.undo.iter_mut().chain(self.redo.iter_mut()) {
            entry.before.rebase_paths(&old_dir, new_dir);
        }
        self.path = Some(path.to_path_buf());
        self.saved = self.project.clone();
        let _ = std::fs::remove_file(&old_recovery);
        let _ = std::fs::remove_file(recovery_path(self.path.as_deref()));
        self.autosaved_revision = self.revision;
        Ok(())
    }

    /// Writes the recovery file when there are unsaved changes not yet autosaved and
    /// `interval` has passed since the last autosave. Returns the file written.
    pub fn autosave(&mut self, interval: Duration) -> Result<Option<PathBuf>> {
        if self.revision == self.autosaved_revision || self.last_autosave.elapsed() < interval {
            return Ok(None);
        }
        self.last_autosave = Instant::now();
        self.autosaved_revision = self.revision;
        let path = recovery_path(self.path.as_deref());
        if !self.is_dirty() {
            let _ = std::fs::remove_file(&path);
            return Ok(None);
        }
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        self.project.save_without_backup(&path)?;
        Ok(Some(path))
    }

    /// Removes the recovery file (on a clean exit that discards or saves the changes).
    pub fn discard_recovery(&self) {
        let _ = std::fs::remove_file(recovery_path(self.path.as_deref()));
    }
}

/// Where Lightloom keeps recent files and recovery files: `$LIGHTLOOM_STATE_DIR`, else
/// `$XDG_STATE_HOME/lightloom`, else `~/.local/state/lightloom`.
pub fn state_dir() -> PathBuf {
    crate::user_dirs::user_dir("LIGHTLOOM_STATE_DIR", "XDG_STATE_HOME", ".local/state")
}

/// The recovery file of a project (`None`: the untitled/built-in project): one per project
/// path, named after the file and a hash of its absolute path.
pub fn recovery_path(project: Option<&Path>) -> PathBuf {
    let dir = state_dir().join("recovery");
    match project {
        None => dir.join("untitled.ron"),
        Some(p) => {
            let absolute = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
            let hash = xxhash_rust::xxh3::xxh3_64(absolute.to_string_lossy().as_bytes());
            let stem = p.file_stem().map_or("project".into(), |s| s.to_string_lossy().into_owned());
            dir.join(format!("{stem}-{hash:016x}.ron"))
        }
    }
}

/// A recovery file left by a session that did not close cleanly, if it is newer than the
/// project file it belongs to.
pub fn pending_recovery(project: Option<&Path>) -> Option<(PathBuf, std::time::SystemTime)> {
    let recovery = recovery_path(project);
    let saved_at = std::fs::metadata(&recovery).and_then(|m| m.modified()).ok()?;
    let project_time = project.and_then(|p| std::fs::metadata(p).and_then(|m| m.modified()).ok());
    match project_time {
        Some(t) if t > saved_at => None,
        _ => Some((recovery, saved_at)),
    }
}

/// Most recently opened or saved projects, newest first.
pub fn recent_files() -> Vec<PathBuf> {
    std::fs::read_to_string(state_dir().join("recent.txt"))
        .map(|text| text.lines().filter(|l| !l.trim().is_empty()).map(PathBuf::from).collect())
        .unwrap_or_default()
}

/// Puts `path` first in the recent files (at most ten are kept).
pub fn remember_recent(path: &Path) {
    let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut recent = recent_files();
    recent.retain(|p| p != &path);
    recent.insert(0, path);
    recent.truncate(10);
    let dir = state_dir();
    let text: String = recent.iter().map(|p| format!("{}\n", p.display())).collect();
    if std::fs::create_dir_all(&dir).is_ok() {
        let _ = std::fs::write(dir.join("recent.txt"), text);
    }
}

/// One state directory for every test in this process (the variable is process-wide).
#[cfg(test)]
pub(crate) fn test_state_dir() -> PathBuf {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("lightloom-tests-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        // SAFETY: set once, before any test reads them (every test goes through this function).
        unsafe {
            std::env::set_var("LIGHTLOOM_STATE_DIR", dir.join("state"));
            std::env::set_var("LIGHTLOOM_DATA_DIR", dir.join("data"));
        }
        dir
    })
    .clone()
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightloom_nodes::engine::spec::ParamValue;
    use lightloom_nodes::project::default_project;

    fn set_exposure(doc: &mut Document, v: f64, merge: Option<&str>) {
        doc.edit("exposure", merge, |p| {
            let node = p.nodes.iter_mut().find(|n| n.id == "output").unwrap();
            node.params.insert("exposure".into(), ParamValue::Float(v));
            Ok(())
        })
        .unwrap();
    }

    #[test]
    fn undo_and_redo_restore_each_state() {
        let mut doc = Document::new(default_project(), None);
        let original = doc.project.clone();
        set_exposure(&mut doc, 1.0, None);
        let after_one = doc.project.clone();
        set_exposure(&mut doc, 2.0, None);
        assert!(doc.is_dirty());
        assert!(doc.undo());
        assert_eq!(doc.project, after_one);
        assert!(doc.undo());
        assert_eq!(doc.project, original);
        assert!(!doc.is_dirty(), "back to the saved state");
        assert!(!doc.undo());
        assert!(doc.redo() && doc.redo());
        assert_ne!(doc.project, after_one);
        assert!(!doc.redo());
        // A new edit clears the redo stack.
        doc.undo();
        set_exposure(&mut doc, 3.0, None);
        assert!(!doc.redo());
    }

    #[test]
    fn a_drag_is_one_undo_step_and_refused_or_empty_edits_record_nothing() {
        let mut doc = Document::new(default_project(), None);
        let original = doc.project.clone();
        for v in [0.1, 0.2, 0.3, 0.4] {
            set_exposure(&mut doc, v, Some("output.exposure"));
        }
        doc.seal();
        set_exposure(&mut doc, 0.5, Some("output.exposure"));
        doc.undo();
        doc.undo();
        assert_eq!(doc.project, original, "two undo steps: the drag and the later edit");
        let revision = doc.revision();
        assert!(
            doc.edit("refused", None, |p| {
                p.name.push('x');
                Err::<(), _>("no".into())
            })
            .is_err()
        );
        assert_eq!(doc.project, original, "a refused edit changes nothing");
        doc.edit("nothing", None, |_| Ok(())).unwrap();
        assert_eq!(doc.revision(), revision);
        assert_eq!(doc.undo_label(), None);
    }

    #[test]
    fn save_autosave_and_recovery() {
        let dir = test_state_dir().join("document");
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("scene.ron");
        let mut doc = Document::new(default_project(), None);
        doc.save_as(&path).unwrap();
        assert!(!doc.is_dirty());
        let reopened = Document::open(&path).unwrap();
        assert_eq!(reopened.project, doc.project, "save and reload round-trips");

        set_exposure(&mut doc, 1.5, None);
        let written = doc.autosave(Duration::ZERO).unwrap().expect("a dirty document autosaves");
        assert_eq!(written, recovery_path(Some(&path)));
        let (found, _) = pending_recovery(Some(&path)).expect("the crash leaves a recovery file");
        let recovered = Document::open(&found).unwrap();
        assert_eq!(recovered.project, doc.project, "the recovery file holds the unsaved edit");
        assert_eq!(doc.autosave(Duration::ZERO).unwrap(), None, "nothing new to autosave");

        doc.save_as(&path).unwrap();
        assert!(pending_recovery(Some(&path)).is_none(), "saving clears the recovery file");
        remember_recent(&path);
        remember_recent(&dir.join("other.ron"));
        remember_recent(&path);
        let recent: Vec<_> = recent_files().into_iter().filter(|p| p.starts_with(&dir)).collect();
        assert_eq!(recent.len(), 2);
        assert!(recent[0].ends_with("scene.ron"));
    }
}
