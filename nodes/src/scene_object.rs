//! The objects a Scene node lists (its `objects` parameter, stored in project files): plain
//! data, so the graph model can hold them without depending on the Scene kind. Meshing and
//! transforms live in [`crate::kinds::scene`].

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
    /// A glTF 2.0 model (a file relative to the project; its own node transforms apply
    /// inside the object, and its base colours are multiplied by the object's colour / 0.8).
    Gltf {
        file: String,
    },
}

impl SceneObject {
    /// The model file a glTF object names (relative to the project), if any.
    pub fn file(&self) -> Option<&str> {
        match &self.shape {
            Shape::Gltf { file } if !file.is_empty() => Some(file),
            _ => None,
        }
    }

    pub fn file_mut(&mut self) -> Option<&mut String> {
        match &mut self.shape {
            Shape::Gltf { file } if !file.is_empty() => Some(file),
            _ => None,
        }
    }
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
    /// Precompute a per-texel visibility texture over the object's UVs (Ma et al. §3.4), so a
    /// coarse mesh such as a floor quad still receives sharp shadows.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub visibility_texture: bool,
    /// Id of the BRDF editor node (linked to the Output's `material` input) that shades this
    /// object; empty for the first linked material.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub material: String,
    /// Box-projected texture coordinates, one unit per this many metres, for the object's
    /// meshes that have none (a glTF model exported without UVs), so a normal map applies to
    /// them ([`crate::mesh::Mesh::box_projected`]); `None` leaves such meshes without. The
    /// projected coordinates overlap, so those meshes take no visibility texture.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub box_uvs: Option<f64>,
}

fn unit_scale() -> [f64; 3] {
    [1.0; 3]
}

pub(crate) fn grey() -> [f64; 3] {
    [0.8; 3]
}
