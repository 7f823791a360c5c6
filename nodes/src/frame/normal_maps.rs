//! A material's normal map in a frame ([`crate::normal_filtering`]): what the frame requests
//! and what the viewport samples.

use super::*;
use crate::brdf::Model;
use crate::kinds::brdf_normal_map::{NormalFilter, NormalSettings};

/// A material's normal map as a frame shades it ([`crate::normal_filtering`]).
#[derive(Clone, Debug)]
pub struct NormalDetail {
    pub settings: crate::kinds::brdf_normal_map::NormalSettings,
    /// [`crate::normal_filtering::NormalMap`].
    pub map: Keyed,
    /// [`crate::normal_filtering::MomentPyramid`].
    pub moments: Keyed,
    /// [`crate::normal_filtering::VmfPyramid`], with the vMF filter once fitted (until then
    /// highlights take the SH filter's lobe).
    pub lobes: Option<Keyed>,
}

/// The materials' normal maps for the viewport (`shaders/normal_map.wgsl`): per material its
/// map's pyramids, all of one size (the texture array's layers), and the irradiance of the light
/// the mode's transport carries, by which modes that light per vertex scale their diffuse
/// light per pixel.
#[derive(Clone, Debug, Default)]
pub struct NormalMapFrame {
    /// Per material (as the frame's), its normal map, or `None`.
    pub materials: Vec<Option<NormalDetail>>,
    /// `E_lm = Â_l L_lm` to band 2 of the light the mode's diffuse transport carries, when the
    /// mode shades diffuse light per vertex: each pixel's diffuse light is scaled by this
    /// irradiance averaged over its NDF over the same at its geometric normal (1 on a flat map).
    pub vertex_diffuse_scale: Option<ShRgb>,
    /// In the modes that shade the environment's light per vertex, while a material has a map:
    /// what each pixel corrects its highlight by; in the SH modes
    /// ([`Mode::prefilters_highlight`]), with a glossy material, also the prefiltered light their
    /// highlight is drawn from.
    pub vertex_highlight: Option<VertexHighlight>,
}

/// Bands of the light a per-vertex highlight is corrected with.
pub const HIGHLIGHT_BANDS: usize = 8;

/// How a pixel corrects its mode's per-vertex environment highlight for its normal map: by what
/// its NDF does to the highlight H of `radiance`, the unshadowed light the highlight carries,
/// through the material's equivalent Phong lobe (Han et al. 2007: per SH band, the lobe's factor
/// times the normals' spread, `f_l e^{−2l(l+1)/κ}` for a vMF lobe of normals, the mirror
/// direction spreading twice as far). Light the NDF turns away scales the vertices' highlight
/// by H through the NDF over H at the normal; light it turns in is added, scaled by how open the
/// vertex is to that light (its transported irradiance over the unshadowed one). A flat map
/// changes nothing.
#[derive(Clone, Debug)]
pub struct VertexHighlight {
    /// `L_lm` to [`HIGHLIGHT_BANDS`].
    pub radiance: ShRgb,
    /// Per material, its glossy lobe to [`HIGHLIGHT_BANDS`] (`None` for Lambert).
    pub lobes: Vec<Option<crate::prt::GlossyLobe>>,
    /// Per material, the shape its lobe reflects the light with
    /// ([`crate::reflected_lobe::table`]).
    pub shapes: Vec<crate::reflected_lobe::LobeShape>,
    /// The same light GGX-prefiltered ([`crate::specular_cube::SpecularCube`]), once
    /// evaluated: H then comes from it, each lobe as the GGX lobe of its equivalent Phong
    /// exponent widened by the normals' spread, sharp where band 7 blurs.
    pub cube: Option<Keyed>,
}

impl NormalMapFrame {
    /// The materials' maps for the viewport in `mode`; a map of another size than the first
    /// mapped material's is left out, and `notes` says so as `(node, why)`.
    pub fn new(
        materials: &[FrameMaterial],
        transported: Option<&ShRgb>,
        cube: Option<&Keyed>,
        mode: Mode,
        notes: &mut Vec<(String, String)>,
    ) -> Self {
        // Whether the mode shades the environment's light per vertex.
        let per_vertex = mode.is_shadowed();
        let size = |d: &NormalDetail| {
            d.moments
                .value
                .get::<crate::normal_filtering::MomentPyramid>()
                .and_then(|p| p.levels.first())
                .map(|l| (l.width, l.height))
        };
        let mut common = None;
        let materials_mapped = materials
            .iter()
            .map(|m| {
                let detail = m.normal.as_ref()?;
                let this = size(detail).filter(|s| s.0 > 0)?;
                let first = common.get_or_insert_with(|| (this, m.node.clone())).clone();
                if first.0 != this {
                    notes.push((
                        m.node.clone(),
                        format!(
                            "its {}×{} normal map is not shown: the viewport draws normal maps of one size, and `{}`'s is {}×{}",
                            this.0, this.1, first.1, first.0 .0, first.0 .1
                        ),
                    ));
                    return None;
                }
                Some(detail.clone())
            })
            .collect();
        let frame_materials = materials;
        let materials: Vec<Option<NormalDetail>> = materials_mapped;
        let vertex_diffuse_scale = transported.filter(|_| per_vertex).map(|light| light.irradiance().truncated(3));
        let mapped = materials.iter().any(Option::is_some);
        let prefiltered =
            mode.prefilters_highlight() && frame_materials.iter().any(|m| m.material.model != Model::Lambert);
        let vertex_highlight =
            transported.filter(|_| per_vertex && (mapped || prefiltered)).map(|light| VertexHighlight {
                radiance: light.truncated(HIGHLIGHT_BANDS),
                lobes: frame_materials.iter().map(|m| crate::prt::glossy_lobe(&m.material, HIGHLIGHT_BANDS)).collect(),
                shapes: frame_materials
                    .iter()
                    .map(|m| crate::reflected_lobe::LobeShape::of(m.material.model))
                    .collect(),
                cube: cube.cloned(),
            });
        Self { materials, vertex_diffuse_scale, vertex_highlight }
    }

    /// Whether pixels shade through this frame's maps or highlight light (the viewport's
    /// pipelines that read them).
    pub fn shaded(&self) -> bool {
        self.materials.iter().any(Option::is_some) || self.vertex_highlight.is_some()
    }
}

/// A normal map is sampled at texture coordinates: on a mesh without them it does not apply (the
/// viewport draws such a mesh unmapped, as the reference does; [`crate::mesh::VertexFrames`]).
/// Per material whose map the frame shows, the meshes it leaves unmapped go to `notes`.
pub(super) fn note_meshes_without_uvs(
    geometry: &Geometry,
    materials: &[FrameMaterial],
    maps: &NormalMapFrame,
    notes: &mut Vec<(String, String)>,
) {
    let Some(set) = geometry.meshes.value.get::<crate::mesh::MeshSet>() else { return };
    for (index, material) in materials.iter().enumerate() {
        if !maps.materials.get(index).is_some_and(Option::is_some) {
            continue;
        }
        // Per scene object (a glTF's meshes are named `object/mesh`), how many of its meshes.
        let mut objects: Vec<(&str, usize)> = Vec::new();
        let without = set
            .meshes
            .iter()
            .zip(&geometry.mesh_materials)
            .filter(|(mesh, m)| **m as usize == index && mesh.uvs.len() != mesh.positions.len());
        for (mesh, _) in without {
            let object = mesh.name.split('/').next().unwrap_or(&mesh.name);
            match objects.iter_mut().find(|(name, _)| *name == object) {
                Some((_, count)) => *count += 1,
                None => objects.push((object, 1)),
            }
        }
        if objects.is_empty() {
            continue;
        }
        let named: Vec<String> = objects
            .iter()
            .take(3)
            .map(|(name, count)| if *count > 1 { format!("`{name}` ({count} meshes)") } else { format!("`{name}`") })
            .collect();
        let more = if objects.len() > 3 { format!(" and {} more", objects.len() - 3) } else { String::new() };
        let one = objects.len() == 1;
        notes.push((
            material.node.clone(),
            format!(
                "its normal map does not apply to {}{more}: {} no texture coordinates, so {} drawn without it; \
                 ticking Box UVs on the object (`box_uvs` in the project file) projects some",
                named.join(", "),
                if one { "it has" } else { "they have" },
                if one { "it is" } else { "they are" },
            ),
        ));
    }
}

/// The stages of `material`'s normal map a frame shades with: none without a map; the vMF
/// lobes only where that filter is chosen.
pub fn normal_map_stages(graph: &Graph, material: &str) -> Vec<StageRef> {
    let Some(node) = graph.node(material) else { return Vec::new() };
    if !matches!(node.params.get("normal_map"), Some(ParamValue::Path(p)) if !p.is_empty()) {
        return Vec::new();
    }
    let mut stages: Vec<StageRef> =
        ["normal_map", "ndf_moments", "normal_settings"].map(|s| StageRef::new(material, s)).into();
    if matches!(node.params.get("normal_filter"), Some(ParamValue::Choice(c)) if c == "vmf") {
        stages.push(StageRef::new(material, "vmf_lobes"));
    }
    stages
}

/// `material`'s normal map for a frame, from what `keyed` finds evaluated; what keeps it from
/// showing, or shows it only in part, goes to `notes` as `(node, why)`. A map that failed to
/// load leaves the material unmapped, never the frame undrawn.
pub(super) fn normal_detail(
    keyed: &dyn Fn(&str, &str) -> Result<super::Keyed, String>,
    graph: &Graph,
    material: &str,
    mode: Mode,
    notes: &mut Vec<(String, String)>,
) -> Option<super::NormalDetail> {
    if normal_map_stages(graph, material).is_empty() {
        return None;
    }
    let mut note = |why: String| notes.push((material.to_string(), why));
    let found = (|| {
        let settings = keyed(material, "normal_settings")?;
        let settings = *settings.value.expect::<NormalSettings>().map_err(|e| e.to_string())?;
        Ok::<_, String>((settings, keyed(material, "normal_map")?, keyed(material, "ndf_moments")?))
    })();
    let (settings, map, moments) = match found {
        Ok(found) => found,
        Err(e) => {
            note(format!("its normal map is not shown: {e}"));
            return None;
        }
    };
    let lobes = match settings.filter {
        NormalFilter::Vmf => match keyed(material, "vmf_lobes") {
            Ok(lobes) => Some(lobes),
            Err(e) => {
                note(format!("its normal map's vMF lobes are not ready ({e}): highlights take the SH filter's lobe"));
                None
            }
        },
        _ => None,
    };
    if let Some(node) = graph.node(material) {
        let model = node_model(node);
        let anisotropic = matches!(node.params.get("anisotropy"), Some(ParamValue::Float(a)) if *a != 0.0);
        let lobe = match model {
            Model::Phong => Some("Phong's lobe is about the mirror direction, not the half vector"),
            Model::Ward => Some("Ward's lobe is anisotropic"),
            Model::GgxAnisotropic if anisotropic => Some("anisotropic GGX is not radially symmetric"),
            Model::Lambert | Model::BlinnPhong | Model::Ggx | Model::GgxAnisotropic => None,
        };
        if let Some(why) = lobe {
            note(format!(
                "its normal map filters the highlight approximately: {why} (exact for Lambert, Blinn-Phong and GGX)"
            ));
        }
        if model != Model::Lambert && mode != Mode::ShIrradiance && !mode.prefilters_highlight() {
            note(format!(
                "in {mode} the environment's highlight is shaded per vertex and corrected per pixel for the normal \
                 map by the ratio of the prefiltered light through the pixel's normals to that at its normal (the \
                 light's SH to band {} until it is prefiltered): the map reshapes the vertices' highlight, it does \
                 not sharpen it",
                super::HIGHLIGHT_BANDS - 1
            ));
        }
    }
    Some(super::NormalDetail { settings, map, moments, lobes })
}

/// The BRDF model a material node's parameters name (Lambert, its default, when they name none).
pub(super) fn node_model(node: &crate::engine::GraphNode) -> Model {
    match node.params.get("model") {
        Some(ParamValue::Choice(c)) => c.parse().unwrap_or(Model::Lambert),
        _ => Model::Lambert,
    }
}
