//! Project files: RON, versioned with migrations, saved atomically with a backup.
//!
//! See `projects/README.md` for the schema with an example.

use crate::engine::spec::ParamValue;
use crate::engine::{Graph, GraphError, Link, graph::NodeInput};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The version this build writes.
pub const CURRENT_VERSION: u32 = 4;

/// A project: cameras, render settings, nodes and links.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Project {
    pub version: u32,
    #[serde(default)]
    pub name: String,
    #[serde(default)]
    pub cameras: Vec<Camera>,
    #[serde(default)]
    pub render: RenderSettings,
    /// The editor's view when the project was saved: the editor reopens on it, and
    /// `lightloom render` renders it unless a camera is named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<Camera>,
    pub nodes: Vec<ProjectNode>,
    #[serde(default)]
    pub links: Vec<ProjectLink>,
}

/// `a/b/../c` → `a/c` (lexically; the file need not exist).
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir if out.file_name().is_some() => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// A perspective camera looking from `position` at `target`, +Y up.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    pub name: String,
    pub position: [f64; 3],
    pub target: [f64; 3],
    /// Vertical field of view, degrees.
    #[serde(default = "default_fov")]
    pub fov_y_deg: f64,
}

fn default_fov() -> f64 {
    45.0
}

/// Defaults for `lightloom render` and the viewport.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Camera name; empty means the first camera.
    pub camera: String,
    /// Output node id; empty means the only Output node.
    pub output: String,
}

impl RenderSettings {
    /// The Output node chosen, if one is named.
    pub fn output_node(&self) -> Option<&str> {
        Some(self.output.as_str()).filter(|s| !s.is_empty())
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self { width: 960, height: 540, camera: String::new(), output: String::new() }
    }
}

/// A node instance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectNode {
    pub id: String,
    pub kind: String,
    /// Display name in the editor (defaults to the id).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub label: String,
    /// Position in the graph editor.
    #[serde(default)]
    pub position: [f32; 2],
    /// Parameters that differ from the kind's defaults (all of them after a save).
    #[serde(default)]
    pub params: BTreeMap<String, ParamValue>,
}

/// A link `from: (node, output port)` → `to: (node, input port)`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectLink {
    pub from: (String, String),
    pub to: (String, String),
}

/// Why a project could not be loaded or saved. Messages name the file and, where known, the
/// line:column, node and parameter.
#[derive(Debug, thiserror::Error)]
pub enum ProjectError {
    #[error("cannot read project {path}: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    #[error("{path}:{line}:{column}: {message}")]
    Syntax { path: PathBuf, line: usize, column: usize, message: String },
    #[error(
        "{path}: version {found} is newer than this Lightloom understands (up to {CURRENT_VERSION}); update Lightloom"
    )]
    TooNew { path: PathBuf, found: u32 },
    #[error("{path}: {}", format_graph_errors(errors))]
    Invalid { path: PathBuf, errors: Vec<(Option<usize>, GraphError)> },
    #[error("{path}: {message}")]
    MissingAsset { path: PathBuf, message: String },
    #[error("cannot save project {path}: {cause}")]
    Save { path: PathBuf, cause: std::io::Error },
}

fn format_graph_errors(errors: &[(Option<usize>, GraphError)]) -> String {
    let lines: Vec<String> = errors
        .iter()
        .map(|(line, e)| match line {
            Some(l) => format!("line {l}: {e}"),
            None => e.to_string(),
        })
        .collect();
    if lines.len() == 1 { lines[0].clone() } else { format!("{} problems:\n  {}", lines.len(), lines.join("\n  ")) }
}

#[derive(Deserialize)]
struct VersionProbe {
    #[serde(default)]
    version: u32,
}

impl Project {
    /// Parses RON text (any supported version), migrating to the current version.
    pub fn from_ron(text: &str, path: &Path) -> Result<Self, ProjectError> {
        let syntax = |e: ron::error::SpannedError| ProjectError::Syntax {
            path: path.into(),
            line: e.span.start.line,
            column: e.span.start.col,
            message: e.code.to_string(),
        };
        let options = ron::Options::default();
        let probe: VersionProbe = options.from_str(text).map_err(syntax)?;
        match probe.version {
            CURRENT_VERSION => options.from_str(text).map_err(syntax),
            3 => options.from_str::<Project>(text).map_err(syntax).map(migrate_v3),
            2 => options.from_str::<Project>(text).map_err(syntax).map(migrate_v2).map(migrate_v3),
            1 => {
                let v1: v1::ProjectV1 = options.from_str(text).map_err(syntax)?;
                v1.migrate().map(migrate_v2).map(migrate_v3).map_err(|message| ProjectError::Syntax {
                    path: path.into(),
                    line: 1,
                    column: 1,
                    message,
                })
            }
            0 => Err(ProjectError::Syntax {
                path: path.into(),
                line: 1,
                column: 1,
                message: "missing `version` field (a Lightloom project starts with `(version: 4, ...`)".into(),
            }),
            found if found > CURRENT_VERSION => Err(ProjectError::TooNew { path: path.into(), found }),
            found => Err(ProjectError::Syntax {
                path: path.into(),
                line: 1,
                column: 1,
                message: format!("unknown project version {found}"),
            }),
        }
    }

    /// Loads and validates a project file; returns the project and its graph.
    pub fn load(path: &Path) -> Result<(Self, Graph), ProjectError> {
        Self::load_with_overrides(path, &[])
    }

    /// Loads a project, applies `node.param=value` overrides, then validates it. Validation
    /// errors carry the line where the offending node is declared.
    pub fn load_with_overrides(path: &Path, overrides: &[String]) -> Result<(Self, Graph), ProjectError> {
        remove_stale_temp_files(path);
        crate::limits::check_regular_file(path, MAX_PROJECT_BYTES)
            .map_err(|e| ProjectError::Io { path: path.into(), cause: std::io::Error::other(e) })?;
        let text = std::fs::read_to_string(path).map_err(|source| match source.kind() {
            std::io::ErrorKind::InvalidData => ProjectError::Syntax {
                path: path.into(),
                line: 1,
                column: 1,
                message: "not a text file (invalid UTF-8); a project is a RON text file".into(),
            },
            _ => ProjectError::Io { path: path.into(), cause: source },
        })?;
        let mut project = Self::from_ron(&text, path)?;
        for o in overrides {
            project.apply_override(o).map_err(|message| ProjectError::Invalid {
                path: path.into(),
                errors: vec![(None, GraphError { node: None, port: None, param: None, message })],
            })?;
        }
        let graph = project.graph(path).map_err(|errors| ProjectError::Invalid {
            path: path.into(),
            errors: errors.into_iter().map(|e| (e.node.as_deref().and_then(|n| node_line(&text, n)), e)).collect(),
        })?;
        Ok((project, graph))
    }

    /// Asset files named by parameters that do not exist, as `(node, parameter, path)`.
    pub fn missing_assets(&self, graph: &Graph) -> Vec<(String, String, PathBuf)> {
        let mut missing = Vec::new();
        for node in &graph.nodes {
            for name in node.params.keys() {
                for p in node.files(name) {
                    if !graph.project_dir.join(p).is_file() {
                        missing.push((node.id.clone(), name.clone(), graph.project_dir.join(p)));
                    }
                }
            }
        }
        missing
    }

    /// Builds the evaluable graph; relative asset paths resolve against the project's folder.
    /// View-dependent results (area-light highlights) are for the render camera.
    pub fn graph(&self, path: &Path) -> Result<Graph, Vec<GraphError>> {
        self.graph_seen_from(path, None)
    }

    /// [`Self::graph`] with view-dependent results for `eye` (the render camera's position when
    /// `None`): the Outputs' [`crate::kinds::output::HIGHLIGHT_EYE`].
    pub fn graph_seen_from(&self, path: &Path, eye: Option<[f64; 3]>) -> Result<Graph, Vec<GraphError>> {
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut errors = Vec::new();
        for (i, c) in self.cameras.iter().enumerate() {
            let numbers = c.position.iter().chain(&c.target).chain(std::iter::once(&c.fov_y_deg));
            let limit = f64::from(crate::limits::MAX_COORDINATE);
            let distance = glam::DVec3::from(c.position).distance(glam::DVec3::from(c.target));
            if numbers.clone().any(|v| !v.is_finite() || v.abs() > limit)
                || !(1.0..=170.0).contains(&c.fov_y_deg)
                || distance.is_nan()
                || distance < 1e-6
            {
                errors.push(GraphError {
                    node: None,
                    port: None,
                    param: None,
                    message: format!(
                        "camera {i} (`{}`): needs coordinates within ±{limit:e} m, fov_y_deg in 1..=170, and a \
                         target apart from its position",
                        c.name
                    ),
                });
            }
        }
        let (w, h) = (self.render.width, self.render.height);
        if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
            errors.push(GraphError {
                node: None,
                port: None,
                param: None,
                message: format!("render size {w}x{h} must be within 1..=16384 on each side"),
            });
        }
        let inputs: Vec<NodeInput> =
            self.nodes.iter().map(|n| NodeInput { id: &n.id, kind: &n.kind, params: &n.params }).collect();
        let links: Vec<Link> = self
            .links
            .iter()
            .map(|l| Link {
                from_node: l.from.0.clone(),
                from_port: l.from.1.clone(),
                to_node: l.to.0.clone(),
                to_port: l.to.1.clone(),
            })
            .collect();
        match Graph::build(&inputs, &links, dir, crate::kinds::registry()) {
            Ok(mut graph) if errors.is_empty() => {
                if let Some(eye) = eye.or_else(|| self.camera(None).ok().map(|c| c.position)) {
                    crate::kinds::output::see_from(&mut graph, eye);
                }
                Ok(graph)
            }
            Ok(_) => Err(errors),
            Err(mut more) => {
                errors.append(&mut more);
                Err(errors)
            }
        }
    }

    /// The camera to render with: the one named (here, else in the render settings), else
    /// the editor's saved view (what the editor showed when the project was saved), else the
    /// first camera, else a default view.
    pub fn camera(&self, name: Option<&str>) -> Result<Camera, String> {
        let name = name.or(Some(self.render.camera.as_str()).filter(|n| !n.is_empty()));
        if name.is_none()
            && let Some(view) = &self.view
        {
            return Ok(view.clone());
        }
        match name {
            Some(n) => self.cameras.iter().find(|c| c.name == n).cloned().ok_or_else(|| {
                let known: Vec<&str> = self.cameras.iter().map(|c| c.name.as_str()).collect();
                format!(
                    "no camera named `{n}` (cameras: {})",
                    if known.is_empty() { "none".into() } else { known.join(", ") }
                )
            }),
            None => Ok(self.cameras.first().cloned().unwrap_or(Camera {
                name: "default".into(),
                position: [0.0, 2.0, 6.0],
                target: [0.0, 0.5, 0.0],
                fov_y_deg: 45.0,
            })),
        }
    }

    /// Rewrites relative file names for a project file moving from `from_dir` to `to_dir`:
    /// each names the same file as before, relative to `to_dir` where that is short (at most
    /// three `..`), absolute otherwise. Absolute names stay as they are; nothing changes when
    /// the folder does not.
    pub fn rebase_paths(&mut self, from_dir: &Path, to_dir: &Path) {
        let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let (from_dir, to_dir) = (absolute(from_dir), absolute(to_dir));
        if from_dir == to_dir {
            return;
        }
        for node in &mut self.nodes {
            for text in node.params.values_mut().flat_map(ParamValue::files_mut) {
                if Path::new(text.as_str()).is_absolute() {
                    continue;
                }
                let file = normalize(&from_dir.join(&*text));
                let relative = pathdiff::diff_paths(&file, &to_dir)
                    .filter(|r| r.components().filter(|c| matches!(c, std::path::Component::ParentDir)).count() <= 3);
                // Forward slashes, so the project reads the same on every system.
                *text = relative.unwrap_or(file).to_string_lossy().replace('\\', "/");
            }
        }
    }

    /// RON text with a stable order (nodes and links as listed; parameters sorted).
    pub fn to_ron(&self) -> String {
        let config = ron::ser::PrettyConfig::new().depth_limit(6).indentor("    ".to_string());
        let mut text = ron::ser::to_string_pretty(self, config).expect("projects serialise");
        text.push('\n');
        text
    }

    /// Saves atomically: write a temporary file, fsync, keep the previous file as `NAME.bak`,
    /// rename into place, fsync the folder. The target never exists half-written.
    pub fn save(&self, path: &Path) -> Result<(), ProjectError> {
        self.write_atomically(path, true)
    }

    /// Saves atomically without keeping a `.bak` (autosave and recovery files).
    pub fn save_without_backup(&self, path: &Path) -> Result<(), ProjectError> {
        self.write_atomically(path, false)
    }

    fn write_atomically(&self, path: &Path, backup: bool) -> Result<(), ProjectError> {
        remove_stale_temp_files(path);
        let save_err = |cause| ProjectError::Save { path: path.into(), cause };
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let file_name =
            path.file_name().ok_or_else(|| save_err(std::io::Error::other("not a file path")))?.to_string_lossy();
        let mut file = tempfile::Builder::new().prefix(&format!(".{file_name}.")).tempfile_in(dir).map_err(save_err)?;
        file.write_all(self.to_ron().as_bytes()).map_err(save_err)?;
        keep_permissions(file.as_file(), path).map_err(save_err)?;
        file.as_file().sync_all().map_err(save_err)?;
        if backup && path.exists() {
            let bak =
                tempfile::Builder::new().prefix(&format!(".{file_name}.bak.")).tempfile_in(dir).map_err(save_err)?;
            std::fs::copy(path, bak.path()).map_err(save_err)?;
            bak.persist(dir.join(format!("{file_name}.bak"))).map_err(|e| save_err(e.error))?;
        }
        file.persist(path).map_err(|e| save_err(e.error))?;
        if let Ok(d) = std::fs::File::open(dir) {
            let _ = d.sync_all();
        }
        Ok(())
    }

    /// Applies `node.param=value` overrides (command line `--set`).
    pub fn apply_override(&mut self, assignment: &str) -> Result<(), String> {
        let (node_id, param, value) = self.parse_override(assignment)?;
        let node = self.nodes.iter_mut().find(|n| n.id == node_id).expect("parse_override found the node");
        node.params.insert(param, value);
        Ok(())
    }

    /// `NODE.PARAM=VALUE` as the node, the parameter and the value it names, checked against
    /// the node kind's parameter.
    pub fn parse_override(&self, assignment: &str) -> Result<(String, String, ParamValue), String> {
        let (target, value) =
            assignment.split_once('=').ok_or_else(|| format!("`{assignment}` is not NODE.PARAM=VALUE"))?;
        let (node_id, param) = target.split_once('.').ok_or_else(|| format!("`{target}` is not NODE.PARAM"))?;
        let node = self
            .nodes
            .iter()
            .find(|n| n.id == node_id)
            .ok_or_else(|| format!("--set {assignment}: no node `{node_id}`"))?;
        let kind = crate::kinds::kind(&node.kind)
            .ok_or_else(|| format!("--set {assignment}: node `{node_id}` has unknown kind"))?;
        let spec = kind.param(param).ok_or_else(|| {
            let known: Vec<&str> = kind.params.iter().map(|p| p.name).collect();
            format!("--set {assignment}: {} has no parameter `{param}` (known: {})", kind.name, known.join(", "))
        })?;
        let parsed = ParamValue::parse_for(&spec.kind, value).map_err(|e| format!("--set {assignment}: {e}"))?;
        spec.check(&parsed).map_err(|e| format!("--set {assignment}: {e}"))?;
        Ok((node_id.to_string(), param.to_string(), parsed))
    }
}

/// The 1-based line where node `id` is declared, if it can be found.
fn node_line(text: &str, id: &str) -> Option<usize> {
    let needle = format!("\"{id}\"");
    text.lines().position(|l| l.contains("id:") && l.contains(&needle)).map(|i| i + 1)
}

/// Version 2 → 3: evaluation became demand-driven. The Scene's `transport` choice is gone
/// (each relighting mode computes the transport it reads), and the Output's default mode
/// became shadowed, so a v2 Output without a mode keeps v2's default, `sh_irradiance`.
fn migrate_v2(mut project: Project) -> Project {
    for node in &mut project.nodes {
        match node.kind.as_str() {
            "Scene" => {
                node.params.remove("transport");
            }
            "Output" => {
                node.params.entry("mode".into()).or_insert_with(|| ParamValue::Choice("sh_irradiance".into()));
            }
            _ => {}
        }
    }
    project.version = 3;
    project
}

/// Version 3 → 4: a glTF model became a scene object (with a transform, colour and material)
/// instead of the Scene's `file` parameter; the model keeps its place.
fn migrate_v3(mut project: Project) -> Project {
    for node in project.nodes.iter_mut().filter(|n| n.kind == "Scene") {
        let Some(ParamValue::Path(file)) = node.params.remove("file") else { continue };
        if file.is_empty() {
            continue;
        }
        let stem = Path::new(&file).file_stem().map_or("model".into(), |s| s.to_string_lossy().into_owned());
        let model = crate::scene_object::SceneObject::new(&stem, crate::scene_object::Shape::Gltf { file });
        match node
            .params
            .entry("objects".into())
            .or_insert_with(|| ParamValue::Objects(crate::kinds::scene::default_objects()))
        {
            ParamValue::Objects(objects) => objects.push(model),
            other => *other = ParamValue::Objects(vec![model]),
        }
    }
    project.version = CURRENT_VERSION;
    project
}

/// Version 1: the first prototype's format (positions as `pos`, links as `"a.port -> b.port"`
/// strings, a single `camera`).
mod v1 {
    use super::*;

    #[derive(Deserialize)]
    pub struct ProjectV1 {
        #[allow(dead_code)]
        pub version: u32,
        #[serde(default)]
        pub name: String,
        pub camera: Option<CameraV1>,
        pub nodes: Vec<NodeV1>,
        #[serde(default)]
        pub links: Vec<String>,
    }

    #[derive(Deserialize)]
    pub struct CameraV1 {
        pub eye: [f64; 3],
        pub look_at: [f64; 3],
        pub fov: f64,
    }

    #[derive(Deserialize)]
    pub struct NodeV1 {
        pub id: String,
        pub kind: String,
        #[serde(default)]
        pub pos: (f32, f32),
        #[serde(default)]
        pub params: BTreeMap<String, ParamValue>,
    }

    impl ProjectV1 {
        pub fn migrate(self) -> Result<Project, String> {
            let links = self
                .links
                .iter()
                .map(|l| {
                    let (from, to) =
                        l.split_once("->").ok_or_else(|| format!("link `{l}` is not `a.port -> b.port`"))?;
                    let split = |s: &str| {
                        s.trim()
                            .split_once('.')
                            .map(|(n, p)| (n.to_string(), p.to_string()))
                            .ok_or_else(|| format!("`{s}` in link `{l}` is not node.port"))
                    };
                    Ok(ProjectLink { from: split(from)?, to: split(to)? })
                })
                .collect::<Result<Vec<_>, String>>()?;
            Ok(Project {
                version: CURRENT_VERSION,
                name: self.name,
                cameras: self
                    .camera
                    .into_iter()
                    .map(|c| Camera { name: "main".into(), position: c.eye, target: c.look_at, fov_y_deg: c.fov })
                    .collect(),
                render: RenderSettings::default(),
                view: None,
                nodes: self
                    .nodes
                    .into_iter()
                    .map(|n| ProjectNode {
                        id: n.id,
                        kind: n.kind,
                        label: String::new(),
                        position: [n.pos.0, n.pos.1],
                        params: n.params,
                    })
                    .collect(),
                links,
            })
        }
    }
}

/// Gives a temporary file the permissions of the file it replaces (a new file: `rw-r--r--`
/// less the umask's usual group and other write bits), not the temporary file's private ones.
pub fn keep_permissions(file: &std::fs::File, replaced: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(replaced).map(|m| m.permissions().mode()).unwrap_or(0o644);
        file.set_permissions(std::fs::Permissions::from_mode(mode))?;
    }
    #[cfg(not(unix))]
    let _ = (file, replaced);
    Ok(())
}

/// The built-in default project: procedural sky, a sphere and a torus on a floor with a
/// visibility texture, in the all-frequency per-pixel mode (sharp sun shadows).
pub fn default_project() -> Project {
    let node = |id: &str, kind: &str, x: f32, y: f32| ProjectNode {
        id: id.into(),
        kind: kind.into(),
        label: String::new(),
        position: [x, y],
        params: BTreeMap::new(),
    };
    let link =
        |a: &str, p: &str, b: &str, q: &str| ProjectLink { from: (a.into(), p.into()), to: (b.into(), q.into()) };
    Project {
        version: CURRENT_VERSION,
        name: "Default: sphere and torus under a procedural sky".into(),
        cameras: vec![Camera {
            name: "main".into(),
            position: [0.0, 2.2, 5.5],
            target: [0.0, 0.6, 0.0],
            fov_y_deg: 40.0,
        }],
        render: RenderSettings::default(),
        view: None,
        nodes: vec![
            node("sky", "EnvironmentMap", 0.0, 0.0),
            node("scene", "Scene", 0.0, 200.0),
            node("material", "BrdfEditor", 0.0, 400.0),
            ProjectNode {
                params: BTreeMap::from([("mode".into(), ParamValue::Choice("wavelet_pixel".into()))]),
                ..node("output", "Output", 320.0, 150.0)
            },
        ],
        links: vec![
            link("sky", "environment", "output", "environment"),
            link("scene", "scene", "output", "scene"),
            link("material", "material", "output", "material"),
        ],
    }
}

/// Largest project file read.
pub const MAX_PROJECT_BYTES: u64 = 64 << 20;

/// Removes temporary files an interrupted atomic write of `path` left next to it (a save or
/// image write killed before its rename): `.NAME.XXXXXX[.ext]` and `.NAME.bak.XXXXXX`, the
/// names `tempfile` gives them here. Runs before each save and load of `path`.
pub fn remove_stale_temp_files(path: &Path) {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let (Some(name), Ok(entries)) = (path.file_name(), std::fs::read_dir(dir)) else { return };
    let prefix = format!(".{}.", name.to_string_lossy());
    let ext = path.extension().map(|e| format!(".{}", e.to_string_lossy())).unwrap_or_default();
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().to_string();
        let Some(rest) = file.strip_prefix(&prefix) else { continue };
        let rest = rest.strip_prefix("bak.").unwrap_or(rest);
        let random = rest.strip_suffix(ext.as_str()).filter(|r| r.len() == 6).unwrap_or(rest);
        if random.len() == 6 && random.chars().all(|c| c.is_ascii_alphanumeric()) && entry.path().is_file() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn saving_elsewhere_keeps_file_parameters_naming_the_same_files() {
        let mut project = super::default_project();
        let set = |p: &mut super::Project, v: &str| {
            p.nodes[0].params.insert("file".into(), super::ParamValue::Path(v.into()));
        };
        let get = |p: &super::Project| match p.nodes[0].params.get("file") {
            Some(super::ParamValue::Path(v)) => v.clone(),
            _ => panic!("no file parameter"),
        };
        // From /a/projects to /a/projects/renders: one level down.
        set(&mut project, "../assets/sky.hdr");
        project.rebase_paths(std::path::Path::new("/a/projects"), std::path::Path::new("/a/projects/renders"));
        assert_eq!(get(&project), "../../assets/sky.hdr"); // not-a-checkout-path
        // Absolute names stay absolute.
        set(&mut project, "/a/projects/renders/maps/sky.hdr");
        project.rebase_paths(std::path::Path::new("/x"), std::path::Path::new("/a/projects/renders"));
        assert_eq!(get(&project), "/a/projects/renders/maps/sky.hdr");
        // A relative name that would climb more than three folders becomes absolute.
        set(&mut project, "hdri/sky.hdr");
        project.rebase_paths(std::path::Path::new("/opt/library"), std::path::Path::new("/home/me/work/shots/a"));
        assert_eq!(get(&project), "/opt/library/hdri/sky.hdr");
        // Saving in the same folder changes nothing.
        let far = "../../../../far/sky.hdr"; // not-a-checkout-path: relative to /a/b/c/d/e
        set(&mut project, far);
        project.rebase_paths(std::path::Path::new("/a/b/c/d/e"), std::path::Path::new("/a/b/c/d/e"));
        assert_eq!(get(&project), far);
    }

    use super::*;

    /// What a save killed at each step leaves behind, then the next start: the project reads
    /// whole (old or new), and no temporary file is left.
    #[test]
    fn a_save_killed_at_any_step_leaves_a_readable_project_and_no_temp_files() {
        let dir = std::env::temp_dir().join(format!("lightloom-killed-save-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("scene.ron");
        let old = default_project();
        old.save(&path).unwrap();
        let mut new = default_project();
        new.cameras[0].fov_y_deg = 55.0;
        let new_text = new.to_ron();
        let half = &new_text[..new_text.len() / 2];
        // (temporary files present, whether the rename happened)
        let steps: [(&[(&str, &str)], bool); 4] = [
            (&[(".scene.ron.a1B2c3", half)], false),
            (&[(".scene.ron.a1B2c3", &new_text)], false),
            (&[(".scene.ron.a1B2c3", &new_text), (".scene.ron.bak.Zz9Yy8", half)], false),
            (&[(".scene.ron.bak.Zz9Yy8", &new_text)], true),
        ];
        std::fs::write(dir.join(".scene.ron.notes"), "not ours").unwrap();
        for (leftovers, renamed) in steps {
            old.save(&path).unwrap();
            if renamed {
                std::fs::write(&path, &new_text).unwrap();
            }
            for (name, text) in leftovers {
                std::fs::write(dir.join(name), text).unwrap();
            }
            let (loaded, _) = Project::load(&path).expect("the project reads whole");
            let fov = loaded.cameras[0].fov_y_deg;
            assert_eq!(fov, if renamed { 55.0 } else { old.cameras[0].fov_y_deg });
            let mut names: Vec<String> =
                std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
            names.sort();
            assert_eq!(names, [".scene.ron.notes", "scene.ron", "scene.ron.bak"], "after {leftovers:?}");
        }
    }

    /// A disk that fills up during a save: the save fails with an error naming the file, the
    /// previous project stays whole, and no temporary file is left. The write limit is set in a
    /// child process (this test binary again), so other tests are not affected.
    #[test]
    fn a_full_disk_during_a_save_keeps_the_previous_project() {
        let child = std::env::var_os("LIGHTLOOM_FULL_DISK_CHILD");
        let dir = match &child {
            Some(d) => PathBuf::from(d),
            None => {
                let dir = std::env::temp_dir().join(format!("lightloom-full-disk-{}", std::process::id()));
                let _ = std::fs::remove_dir_all(&dir);
                std::fs::create_dir_all(&dir).unwrap();
                dir
            }
        };
        let path = dir.join("scene.ron");
        let mut big = default_project();
        for i in 0..200 {
            let mut node = big.nodes[0].clone();
            node.id = format!("extra{i}");
            big.nodes.push(node);
        }
        if child.is_none() {
            default_project().save(&path).unwrap();
            let out = std::process::Command::new(std::env::current_exe().unwrap())
                .args(["--exact", "project::tests::a_full_disk_during_a_save_keeps_the_previous_project"])
                .env("LIGHTLOOM_FULL_DISK_CHILD", &dir)
                .output()
                .unwrap();
            assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stdout));
            let (loaded, _) = Project::load(&path).expect("the previous project reads whole");
            assert_eq!(loaded, default_project());
            let names: Vec<String> =
                std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
            assert_eq!(names, ["scene.ron"], "no temporary file is left");
            return;
        }
        // In the child: files may not grow past 8 KiB (as on a full disk), then save.
        unsafe {
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            let limit = libc::rlimit { rlim_cur: 8192, rlim_max: 8192 };
            assert_eq!(libc::setrlimit(libc::RLIMIT_FSIZE, &limit), 0);
        }
        assert!(big.to_ron().len() > 8192);
        let e = big.save_without_backup(&path).unwrap_err().to_string();
        assert!(e.contains("cannot save project") && e.contains("scene.ron"), "{e}");
    }

    #[test]
    fn special_and_huge_files_are_not_read_as_projects() {
        let e = Project::load(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains("not a regular file"), "{e}");
    }
}
