//! The graph model: node kinds with typed ports and typed, ranged, unit-labelled parameters,
//! and the stages each kind computes. Kinds are registered in [`crate::kinds::registry`].

use crate::engine::{StageContext, StageError, StageValue};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The value of one parameter, as stored in project files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ParamValue {
    Float(f64),
    Int(i64),
    Bool(bool),
    /// Three numbers with a unit (angles, positions).
    Vec3([f64; 3]),
    /// Linear RGB.
    Color([f64; 3]),
    /// One of a fixed set of options.
    Choice(String),
    /// A file path, relative to the project file (or absolute). Empty means none.
    Path(String),
    /// Scene objects (the Scene node's object list).
    Objects(Vec<crate::scene_object::SceneObject>),
    /// Spheres `(centre, radius)` (blocker sphere sets).
    Spheres(Vec<([f64; 3], f64)>),
    /// A light texture's paint operations, in order.
    Paint(Vec<crate::paint::PaintOp>),
}

impl ParamValue {
    /// The files the value names (relative to the project): a file path's, or the models of
    /// an object list.
    pub fn files(&self) -> Vec<&str> {
        match self {
            ParamValue::Path(p) if !p.is_empty() => vec![p.as_str()],
            ParamValue::Objects(objects) => objects.iter().filter_map(|o| o.file()).collect(),
            ParamValue::Paint(ops) => ops.iter().filter_map(|op| op.file()).collect(),
            _ => Vec::new(),
        }
    }

    /// Mutable access to every file name in the value.
    pub fn files_mut(&mut self) -> Vec<&mut String> {
        match self {
            ParamValue::Path(p) if !p.is_empty() => vec![p],
            ParamValue::Objects(objects) => objects.iter_mut().filter_map(|o| o.file_mut()).collect(),
            ParamValue::Paint(ops) => ops.iter_mut().filter_map(|op| op.file_mut()).collect(),
            _ => Vec::new(),
        }
    }

    pub fn type_name(&self) -> &'static str {
        match self {
            ParamValue::Float(_) => "Float",
            ParamValue::Int(_) => "Int",
            ParamValue::Bool(_) => "Bool",
            ParamValue::Vec3(_) => "Vec3",
            ParamValue::Color(_) => "Color",
            ParamValue::Choice(_) => "Choice",
            ParamValue::Path(_) => "Path",
            ParamValue::Objects(_) => "Objects",
            ParamValue::Spheres(_) => "Spheres",
            ParamValue::Paint(_) => "Paint",
        }
    }

    /// Parses a command-line override (`--set node.param=value`) against the parameter's kind.
    pub fn parse_for(kind: &ParamKind, text: &str) -> Result<ParamValue, String> {
        let text = text.trim();
        let float = |s: &str| s.trim().parse::<f64>().map_err(|_| format!("`{s}` is not a number"));
        let triple = |s: &str| -> Result<[f64; 3], String> {
            let parts: Vec<&str> =
                s.trim_matches(|c| c == '(' || c == ')' || c == '[' || c == ']').split(',').collect();
            if parts.len() != 3 {
                return Err(format!("`{s}` is not three comma-separated numbers"));
            }
            Ok([float(parts[0])?, float(parts[1])?, float(parts[2])?])
        };
        Ok(match kind {
            ParamKind::Float { .. } => ParamValue::Float(float(text)?),
            ParamKind::Int { .. } => ParamValue::Int(text.parse().map_err(|_| format!("`{text}` is not an integer"))?),
            ParamKind::Bool { .. } => ParamValue::Bool(match text {
                "true" | "1" | "on" | "yes" => true,
                "false" | "0" | "off" | "no" => false,
                _ => return Err(format!("`{text}` is not true or false")),
            }),
            ParamKind::Vec3 { .. } => ParamValue::Vec3(triple(text)?),
            ParamKind::Color { .. } => ParamValue::Color(triple(text)?),
            ParamKind::Choice { .. } => ParamValue::Choice(text.to_string()),
            ParamKind::Path { .. } => ParamValue::Path(text.to_string()),
            ParamKind::Objects { .. } | ParamKind::Spheres { .. } | ParamKind::Paint => {
                return Err("lists cannot be set from the command line; edit the project".into());
            }
        })
    }
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamValue::Float(v) => write!(f, "{v}"),
            ParamValue::Int(v) => write!(f, "{v}"),
            ParamValue::Bool(v) => write!(f, "{v}"),
            ParamValue::Vec3(v) | ParamValue::Color(v) => write!(f, "({}, {}, {})", v[0], v[1], v[2]),
            ParamValue::Choice(v) | ParamValue::Path(v) => write!(f, "{v}"),
            ParamValue::Objects(v) => write!(f, "{} object(s)", v.len()),
            ParamValue::Spheres(v) => write!(f, "{} sphere(s)", v.len()),
            ParamValue::Paint(v) => write!(f, "{} paint operation(s)", v.len()),
        }
    }
}

/// The type, range and default of a parameter.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamKind {
    Float {
        min: f64,
        max: f64,
        default: f64,
    },
    Int {
        min: i64,
        max: i64,
        default: i64,
    },
    Bool {
        default: bool,
    },
    Vec3 {
        min: f64,
        max: f64,
        default: [f64; 3],
    },
    Color {
        max: f64,
        default: [f64; 3],
    },
    Choice {
        options: &'static [&'static str],
        default: &'static str,
        /// Per option, in the same order: a plain-language label and what it does and costs
        /// (shown in menus and tooltips); empty when the names say enough.
        labels: &'static [(&'static str, &'static str)],
    },
    Path {
        extensions: &'static [&'static str],
        /// Choosing a file also sets this choice parameter to this option (`("source", "file")`):
        /// picking a file means using it.
        selects: Option<(&'static str, &'static str)>,
    },
    Objects {
        default: Vec<crate::scene_object::SceneObject>,
    },
    Spheres {
        default: Vec<([f64; 3], f64)>,
    },
    /// A light texture's paint log (starts empty: a white light).
    Paint,
}

/// A parameter of a node kind.
#[derive(Clone, Debug)]
pub struct ParamSpec {
    pub name: &'static str,
    pub label: &'static str,
    /// Unit label shown beside the value ("deg", "EV", "m", "1/m", "" for none).
    pub unit: &'static str,
    pub kind: ParamKind,
    pub doc: &'static str,
}

impl ParamSpec {
    /// A number within `min..=max`.
    pub fn float(
        name: &'static str,
        label: &'static str,
        unit: &'static str,
        (min, max, default): (f64, f64, f64),
        doc: &'static str,
    ) -> Self {
        Self { name, label, unit, kind: ParamKind::Float { min, max, default }, doc }
    }

    pub fn default_value(&self) -> ParamValue {
        match &self.kind {
            ParamKind::Float { default, .. } => ParamValue::Float(*default),
            ParamKind::Int { default, .. } => ParamValue::Int(*default),
            ParamKind::Bool { default } => ParamValue::Bool(*default),
            ParamKind::Vec3 { default, .. } => ParamValue::Vec3(*default),
            ParamKind::Color { default, .. } => ParamValue::Color(*default),
            ParamKind::Choice { default, .. } => ParamValue::Choice(default.to_string()),
            ParamKind::Path { .. } => ParamValue::Path(String::new()),
            ParamKind::Objects { default } => ParamValue::Objects(default.clone()),
            ParamKind::Spheres { default } => ParamValue::Spheres(default.clone()),
            ParamKind::Paint => ParamValue::Paint(Vec::new()),
        }
    }

    /// Checks type and range; the error says what was expected.
    pub fn check(&self, value: &ParamValue) -> Result<(), String> {
        let finite = |v: f64| if v.is_finite() { Ok(()) } else { Err(format!("{v} is not a finite number")) };
        let num =
            |v: f64| if v != 0.0 && (v.abs() >= 1e6 || v.abs() < 1e-4) { format!("{v:e}") } else { format!("{v}") };
        match (&self.kind, value) {
            (ParamKind::Float { min, max, .. }, ParamValue::Float(v)) => {
                finite(*v)?;
                if v < min || v > max {
                    return Err(format!("{} {} is outside {min}..={max}", num(*v), self.unit).replace("  ", " "));
                }
            }
            (ParamKind::Int { min, max, .. }, ParamValue::Int(v)) => {
                if v < min || v > max {
                    return Err(format!("{v} is outside {min}..={max}"));
                }
            }
            (ParamKind::Bool { .. }, ParamValue::Bool(_)) | (ParamKind::Path { .. }, ParamValue::Path(_)) => {}
            (ParamKind::Vec3 { min, max, .. }, ParamValue::Vec3(v)) => {
                for c in v {
                    finite(*c)?;
                    if c < min || c > max {
                        return Err(format!("component {} is outside {min}..={max}", num(*c)));
                    }
                }
            }
            (ParamKind::Color { max, .. }, ParamValue::Color(v)) => {
                for c in v {
                    finite(*c)?;
                    if *c < 0.0 || c > max {
                        return Err(format!("colour component {} is outside 0..={max}", num(*c)));
                    }
                }
            }
            (ParamKind::Choice { options, .. }, ParamValue::Choice(v)) => {
                if !options.contains(&v.as_str()) {
                    return Err(format!("`{v}` is not one of {}", options.join(", ")));
                }
            }
            (ParamKind::Objects { .. }, ParamValue::Objects(objects)) => {
                for o in objects {
                    o.check()?;
                }
            }
            (ParamKind::Spheres { .. }, ParamValue::Spheres(spheres)) => {
                for (c, r) in spheres {
                    for v in c.iter().chain(std::iter::once(r)) {
                        finite(*v)?;
                    }
                    if *r <= 0.0 || *r > 1e6 {
                        return Err(format!("sphere radius {r} must be in (0, 1e6]"));
                    }
                }
            }
            (ParamKind::Paint, ParamValue::Paint(ops)) => {
                if ops.len() > crate::paint::MAX_OPERATIONS {
                    return Err(format!("{} paint operations; at most {}", ops.len(), crate::paint::MAX_OPERATIONS));
                }
                for op in ops {
                    op.check()?;
                }
            }
            (kind, value) => {
                return Err(format!("expected {}, found {}", kind_name(kind), value.type_name()));
            }
        }
        Ok(())
    }
}

fn kind_name(kind: &ParamKind) -> &'static str {
    match kind {
        ParamKind::Float { .. } => "Float",
        ParamKind::Int { .. } => "Int",
        ParamKind::Bool { .. } => "Bool",
        ParamKind::Vec3 { .. } => "Vec3",
        ParamKind::Color { .. } => "Color",
        ParamKind::Choice { .. } => "Choice",
        ParamKind::Path { .. } => "Path",
        ParamKind::Objects { .. } => "Objects",
        ParamKind::Spheres { .. } => "Spheres",
        ParamKind::Paint => "Paint",
    }
}

/// What flows along a link. Each type is a contract, derived from its readers: the stages an
/// output of that type must offer ([`PortType::read_stages`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PortType {
    /// Distant lighting: radiance cube map, SH and wavelet projections.
    Environment,
    /// A BRDF and its projections.
    Material,
    /// Geometry, receivers and transport.
    Scene,
    /// A participating medium (fog).
    Medium,
    /// Point lights.
    Lights,
    /// A painted planar area light.
    AreaLight,
    /// Sphere sets that cast soft shadows.
    Blockers,
    /// Rotatable square lights decomposed from an environment.
    SquareLights,
}

impl PortType {
    /// The stages a kind offering this type must provide: every stage some kind in `kinds`
    /// reads through an input of this type. The contract is what consumers read, so it grows
    /// with them; [`check_port_contracts`] holds every producer to it.
    pub fn read_stages(self, kinds: &[NodeKindSpec]) -> std::collections::BTreeSet<&'static str> {
        let mut read = std::collections::BTreeSet::new();
        for kind in kinds {
            for stage in &kind.stages {
                for (port, upstream) in stage.inputs {
                    if kind.input(port).is_some_and(|p| p.ty == self) {
                        read.insert(*upstream);
                    }
                }
            }
        }
        read
    }
}

/// Every kind offering an output of some type provides every stage a kind reads through an input
/// of that type ([`PortType::read_stages`]); the first gap, named, otherwise.
pub fn check_port_contracts(kinds: &[NodeKindSpec]) -> Result<(), String> {
    for kind in kinds {
        for out in &kind.outputs {
            for stage in out.ty.read_stages(kinds) {
                if kind.stage(stage).is_none() {
                    return Err(format!(
                        "{} offers {} at `{}` but has no stage {stage}, which its readers read",
                        kind.name, out.ty, out.name
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Parameters and stages a technique adds to every kind whose outputs offer `on`: the scene or
/// material work it needs, kept beside the technique instead of in those kinds (the registry
/// applies them).
#[derive(Clone, Debug)]
pub struct StageExtension {
    pub on: PortType,
    pub params: Vec<ParamSpec>,
    pub stages: Vec<StageSpec>,
}

impl StageExtension {
    /// Adds the parameters and stages to each kind of `kinds` that offers [`Self::on`].
    pub fn apply(&self, kinds: &mut [NodeKindSpec]) {
        for kind in kinds.iter_mut().filter(|k| k.outputs.iter().any(|o| o.ty == self.on)) {
            kind.params.extend(self.params.iter().cloned());
            kind.stages.extend(self.stages.iter().cloned());
        }
    }
}

impl fmt::Display for PortType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

/// An input or output of a node kind.
#[derive(Clone, Debug)]
pub struct PortSpec {
    pub name: &'static str,
    pub ty: PortType,
    /// Inputs only: evaluation fails when a required input is unconnected.
    pub required: bool,
    /// Inputs only: accepts several links (in project order), e.g. the Output's materials.
    pub many: bool,
}

/// The signature of a stage computation.
pub type StageFn = fn(&StageContext) -> Result<StageValue, StageError>;

/// Listed in a stage's `params`, the node's id is part of its key ([`StageContext::node_id`]):
/// for results that follow the node's name (a glTF material taken by name).
pub const NODE_ID: &str = "node id";

/// A stage: a pure function of some parameters, some earlier stages of the same node and some
/// upstream stages (through input ports). Its key hashes exactly these.
#[derive(Clone, Debug)]
pub struct StageSpec {
    pub name: &'static str,
    /// Bumped when the computation changes, invalidating cached results.
    pub version: u32,
    /// The parameters it reads; [`NODE_ID`] among them when its result depends on which node
    /// it belongs to.
    pub params: &'static [&'static str],
    pub stages: &'static [&'static str],
    /// `(input port, upstream stage)` pairs.
    pub inputs: &'static [(&'static str, &'static str)],
    /// Expensive results also go to the on-disk cache, written and read with this codec
    /// (`Some(Codec::of::<T>())` for a stage producing a persisted `T`).
    pub persist: Option<crate::engine::Codec>,
    pub compute: StageFn,
}

/// Whether a kind's technique is in the product yet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Availability {
    Ready,
    /// Parameters and ports are defined; the technique is not implemented (what is missing).
    Planned(&'static str),
}

/// A node kind: what the graph editor offers and the engine evaluates.
#[derive(Clone, Debug)]
pub struct NodeKindSpec {
    pub name: &'static str,
    pub label: &'static str,
    pub doc: &'static str,
    pub inputs: Vec<PortSpec>,
    pub outputs: Vec<PortSpec>,
    pub params: Vec<ParamSpec>,
    pub stages: Vec<StageSpec>,
    /// Pictures the graph editor shows in the node (none for most kinds).
    pub previews: Vec<PreviewSpec>,
    /// How the viewport draws the node and what dragging it edits.
    pub gizmo: GizmoSpec,
    pub availability: Availability,
    /// Whether parameter `name` matters, given the node's parameter values (the inspector
    /// shows only those; evaluation reads every parameter regardless).
    pub relevant: RelevantFn,
    /// Parameters the inspector folds under a header of their own (the rest come first).
    pub groups: &'static [ParamGroup],
    /// Files a parameter's file refers to (a `.gltf`'s buffers and images), whose content keys
    /// the node's stages as the file's own does: editing a `.bin` next to a `.gltf` recomputes
    /// what reads it. [`no_referenced_files`] for kinds whose files stand alone.
    pub referenced_files: ReferencedFilesFn,
}

/// Parameters shown together under a collapsible header, closed at first.
#[derive(Clone, Copy, Debug)]
pub struct ParamGroup {
    pub label: &'static str,
    pub doc: &'static str,
    pub params: &'static [&'static str],
}

/// The files a file refers to, resolved against its folder (see
/// [`NodeKindSpec::referenced_files`]).
pub type ReferencedFilesFn = fn(&std::path::Path) -> Vec<std::path::PathBuf>;

/// For kinds whose files refer to no others.
pub fn no_referenced_files(_: &std::path::Path) -> Vec<std::path::PathBuf> {
    Vec::new()
}

/// Reads the node's parameter values (by name) and says whether parameter `name` matters.
pub type RelevantFn = fn(&dyn Fn(&str) -> Option<ParamValue>, &str) -> bool;

/// For kinds whose every parameter always matters.
pub fn always_relevant(_: &dyn Fn(&str) -> Option<ParamValue>, _: &str) -> bool {
    true
}

impl NodeKindSpec {
    pub fn param(&self, name: &str) -> Option<&ParamSpec> {
        self.params.iter().find(|p| p.name == name)
    }

    pub fn input(&self, name: &str) -> Option<&PortSpec> {
        self.inputs.iter().find(|p| p.name == name)
    }

    pub fn output(&self, name: &str) -> Option<&PortSpec> {
        self.outputs.iter().find(|p| p.name == name)
    }

    pub fn stage(&self, name: &str) -> Option<&StageSpec> {
        self.stages.iter().find(|s| s.name == name)
    }
}

/// A node's handle in the viewport, named by the parameters it shows and edits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum GizmoSpec {
    /// None (or one the editor draws for that kind alone).
    #[default]
    None,
    /// A light at the `Vec3` parameter `position`, in the colour of the `Color` parameter
    /// `colour`, shining along the `Vec3` parameter `aim` when it has one. Dragging moves it.
    Light { position: &'static str, colour: &'static str, aim: Option<&'static str> },
}

/// A picture a node shows in the graph editor, made from some of its stages.
#[derive(Clone, Debug)]
pub struct PreviewSpec {
    /// The stages it reads, requested from the engine while the node is on screen.
    pub stages: &'static [&'static str],
    /// The picture from those stages' values, in order (`None` when one has another type).
    pub make: fn(&[&crate::engine::StageValue]) -> Option<crate::picture::Preview>,
    /// Display size in points.
    pub size: [f32; 2],
    /// What the picture shows (hover text).
    pub caption: &'static str,
}
