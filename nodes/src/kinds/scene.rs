//! Scene node: the objects lit by the graph. Built-in procedural shapes today; glTF files
//! and transport precompute come with the scene issue.

use crate::engine::{StageContext, StageError, StageValue};
use crate::graph::{Availability, NodeKindSpec, ParamKind, ParamSpec, ParamValue, PortSpec, PortType, StageSpec};
use crate::mesh::{self, MeshSet};
use glam::{DMat4, DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// A built-in shape, in object space (sizes in metres).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Shape {
    /// Square in the XZ plane, normal +Y.
    Plane {
        size: f64,
    },
    Sphere {
        radius: f64,
    },
    Box {
        size: [f64; 3],
    },
    /// Around +Y.
    Torus {
        major: f64,
        minor: f64,
    },
    /// Open towards +Z, floor at y = 0, red left and green right walls.
    CornellBox {
        size: f64,
    },
}

/// One object of a scene: a shape, its transform and colour.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneObject {
    pub name: String,
    pub shape: Shape,
    #[serde(default)]
    pub translation: [f64; 3],
    /// Euler angles in degrees, applied as Ry(y) Rx(x) Rz(z).
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    #[serde(default = "unit_scale")]
    pub scale: [f64; 3],
    #[serde(default = "grey")]
    pub color: [f64; 3],
}

fn unit_scale() -> [f64; 3] {
    [1.0; 3]
}

fn grey() -> [f64; 3] {
    [0.8; 3]
}

impl SceneObject {
    pub fn new(name: &str, shape: Shape) -> Self {
        Self { name: name.into(), shape, translation: [0.0; 3], rotation_deg: [0.0; 3], scale: [1.0; 3], color: grey() }
    }

    pub fn at(mut self, translation: [f64; 3]) -> Self {
        self.translation = translation;
        self
    }

    pub fn with_color(mut self, color: [f64; 3]) -> Self {
        self.color = color;
        self
    }

    pub fn transform(&self) -> DMat4 {
        let [x, y, z] = self.rotation_deg.map(f64::to_radians);
        let rotation = DQuat::from_rotation_y(y) * DQuat::from_rotation_x(x) * DQuat::from_rotation_z(z);
        DMat4::from_scale_rotation_translation(DVec3::from(self.scale), rotation, DVec3::from(self.translation))
    }

    /// Range checks with messages naming the object.
    pub fn check(&self) -> Result<(), String> {
        let numbers: Vec<f64> =
            self.translation.iter().chain(&self.rotation_deg).chain(&self.scale).chain(&self.color).copied().collect();
        if numbers.iter().any(|v| !v.is_finite()) {
            return Err(format!("object `{}` has a non-finite number", self.name));
        }
        if self.translation.iter().any(|v| v.abs() > 1e6) {
            return Err(format!("object `{}` is more than 1e6 m from the origin", self.name));
        }
        if self.scale.iter().any(|s| s.abs() < 1e-6 || s.abs() > 1e6) {
            return Err(format!(
                "object `{}` has scale {:?}; each axis must be within 1e-6..1e6 in size",
                self.name, self.scale
            ));
        }
        if self.color.iter().any(|c| *c < 0.0 || *c > 1.0) {
            return Err(format!("object `{}` colour {:?} must be within 0..1", self.name, self.color));
        }
        let sizes: Vec<f64> = match &self.shape {
            Shape::Plane { size } | Shape::CornellBox { size } => vec![*size],
            Shape::Sphere { radius } => vec![*radius],
            Shape::Box { size } => size.to_vec(),
            Shape::Torus { major, minor } => vec![*major, *minor],
        };
        if sizes.iter().any(|s| !s.is_finite() || *s <= 0.0 || *s > 1e6) {
            return Err(format!("object `{}` has a size outside (0, 1e6] m", self.name));
        }
        Ok(())
    }

    /// World-space meshes of the object.
    pub fn meshes(&self, tessellation: usize) -> Vec<mesh::Mesh> {
        let raw = match &self.shape {
            Shape::Plane { size } => vec![mesh::plane(*size, (tessellation / 4).max(1))],
            Shape::Sphere { radius } => vec![mesh::sphere(*radius, tessellation)],
            Shape::Box { size } => vec![mesh::cuboid(*size, (tessellation / 8).max(1), false)],
            Shape::Torus { major, minor } => vec![mesh::torus(*major, *minor, tessellation)],
            Shape::CornellBox { size } => mesh::cornell_box(*size, (tessellation / 8).max(1)),
        };
        let single = raw.len() == 1;
        raw.into_iter()
            .map(|m| {
                let mut m = m.transformed(self.transform());
                let tint = self.color.map(|c| c as f32);
                if single {
                    m.base_color = tint;
                    m.name = self.name.clone();
                } else {
                    m.base_color = [0, 1, 2].map(|c| m.base_color[c] * tint[c] / 0.8);
                    m.name = format!("{}/{}", self.name, m.name);
                }
                m
            })
            .collect()
    }
}

/// The default project's scene: a sphere and a torus on a floor.
pub fn default_objects() -> Vec<SceneObject> {
    vec![
        SceneObject::new("floor", Shape::Plane { size: 8.0 }),
        SceneObject::new("sphere", Shape::Sphere { radius: 0.75 }).at([-0.9, 0.75, 0.0]).with_color([0.9, 0.35, 0.3]),
        SceneObject {
            rotation_deg: [60.0, 20.0, 0.0],
            ..SceneObject::new("torus", Shape::Torus { major: 0.6, minor: 0.22 })
                .at([1.0, 0.75, 0.2])
                .with_color([0.3, 0.5, 0.9])
        },
    ]
}

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "Scene",
        label: "Scene",
        doc: "Objects to light: built-in shapes with transforms and colours.",
        inputs: vec![],
        outputs: vec![PortSpec { name: "scene", ty: PortType::Scene, required: false }],
        params: vec![
            ParamSpec {
                name: "objects",
                label: "Objects",
                unit: "",
                kind: ParamKind::Objects { default: default_objects() },
                doc: "Shapes, transforms and colours.",
            },
            ParamSpec {
                name: "tessellation",
                label: "Tessellation",
                unit: "",
                kind: ParamKind::Int { min: 3, max: 1024, default: 48 },
                doc: "Segments of curved shapes (flat shapes use a quarter).",
            },
        ],
        stages: vec![StageSpec {
            name: "geometry",
            version: 1,
            params: &["objects", "tessellation"],
            stages: &[],
            inputs: &[],
            persist: false,
            compute: geometry,
        }],
        availability: Availability::Ready,
    }
}

fn geometry(ctx: &StageContext) -> Result<StageValue, StageError> {
    let ParamValue::Objects(objects) = ctx.value("objects")? else {
        return Err(StageError::Internal("objects".into()));
    };
    let tessellation = ctx.int("tessellation")? as usize;
    let meshes = objects.iter().flat_map(|o| o.meshes(tessellation)).collect();
    Ok(StageValue::Meshes(MeshSet { meshes }))
}
