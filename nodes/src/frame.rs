//! What one frame draws, per feature: the background, the surfaces (one variant per relighting
//! mode), and the medium and point lights. Gathered from an evaluation by
//! [`crate::kinds::output::FrameInputs::gather`]; renderers upload it as it is. All lighting
//! math (convolution to irradiance, light through fog, table coarsening) happens here, so a
//! renderer only packs and draws.

use crate::brdf::Material;
use crate::engine::{Key, StageValue};
use crate::kinds::output::{Mode, OutputSettings};
use crate::light::PointLight;
use crate::sh::ShRgb;
use crate::single_scattering::FoggedEnvironment;
use std::sync::Arc;

/// Materials one frame can shade with (the shaders' uniform arrays).
pub const MAX_MATERIALS: usize = 8;

/// Point lights one frame can shade with.
pub const MAX_LIGHTS: usize = 8;

/// Irradiance bands shaded per pixel: `Â_l` is 0 for odd `l > 1` and `|Â_6| < 0.016 Â_0`
/// (Sun 2008 eq. 2.24), so bands above 4 add nothing visible.
pub const IRRADIANCE_BANDS: usize = 5;

/// A stage value with its key (renderers re-upload only when the key changes).
#[derive(Clone, Debug)]
pub struct Keyed {
    pub key: Key,
    pub value: Arc<StageValue>,
}

/// Everything one frame draws, per feature.
#[derive(Clone, Debug)]
pub struct FrameInputs {
    pub geometry: Geometry,
    /// The scene's BVH (for the reference renderer and picking), when it was requested.
    pub ray_scene: Option<Keyed>,
    /// The mode drawn: the Output's mode, or [`Mode::ShIrradiance`] while that mode's transport
    /// is still computing (then `pending` says so).
    pub mode: Mode,
    pub pending: Option<String>,
    pub settings: OutputSettings,
    /// Connected inputs the renderer does not draw yet, and material names that matched
    /// nothing, to tell the user.
    pub ignored_inputs: Vec<String>,
    /// Materials whose highlight the mode cannot show as it is: `(node, why and what shows
    /// it)`.
    pub lobe_limits: Vec<(String, String)>,
    /// The materials linked to the Output, in link order (the default material when none is),
    /// at most [`MAX_MATERIALS`].
    pub materials: Vec<FrameMaterial>,
    pub background: Background,
    pub surfaces: Surfaces,
    pub medium: MediumFrame,
    /// Painted area lights, added over any mode's surfaces once their transport is ready.
    pub area_lights: Option<AreaLightFrame>,
    /// The blocker spheres linked to the Output, when evaluated (the reference traces them).
    pub blockers: Option<crate::kinds::blockers::BlockerSet>,
    /// The environment's sun, lit per pixel apart from the mode's transport ([`crate::sun`]).
    pub sun: Option<SunFrame>,
    /// The materials' normal maps as the viewport samples them.
    pub normal_maps: NormalMapFrame,
}

/// A sun disc in world space (the environment's rotation applied), lit per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct SunFrame {
    /// Radiance inside the disc.
    pub radiance: [f64; 3],
    pub solid_angle: f64,
    /// Unit vector to the disc's centre, and the cosine of its angular radius.
    pub axis: [f32; 3],
    pub cos_radius: f64,
    /// Unit vectors towards the disc, spreading it evenly: each stands for
    /// `solid_angle / directions.len()` of it.
    pub directions: Vec<[f32; 3]>,
}

impl SunFrame {
    pub fn new(sun: &crate::sun::Sun) -> Self {
        Self {
            radiance: sun.radiance,
            solid_angle: sun.solid_angle(),
            axis: glam::DVec3::from(sun.direction).as_vec3().to_array(),
            cos_radius: sun.radius.cos(),
            directions: sun.disc_directions(crate::sun::DISC_SAMPLES).iter().map(|d| d.as_vec3().to_array()).collect(),
        }
    }
}

/// The scene's meshes and which material each uses.
#[derive(Clone, Debug)]
pub struct Geometry {
    /// A [`crate::mesh::MeshSet`].
    pub meshes: Keyed,
    /// Per mesh: its index in the frame's materials.
    pub mesh_materials: Vec<u32>,
}

impl Geometry {
    pub fn vertex_count(&self) -> usize {
        self.meshes.value.get::<crate::mesh::MeshSet>().map_or(0, |m| m.meshes.iter().map(|m| m.positions.len()).sum())
    }
}

/// The environment seen behind the scene.
#[derive(Clone, Debug)]
pub struct Background {
    /// The rotated radiance cube map ([`crate::cubemap::CubeMap`]), if an environment is linked.
    pub radiance: Option<Keyed>,
    pub visible: bool,
}

/// One material of a frame, as the reference renderer and the UI see it.
#[derive(Clone, Debug)]
pub struct FrameMaterial {
    /// The BRDF editor node (empty for the default material).
    pub node: String,
    pub material: Material,
    /// Its normal map, once loaded.
    pub normal: Option<NormalDetail>,
}

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
    /// what each pixel corrects its highlight by.
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
#[derive(Clone, Debug, PartialEq)]
pub struct VertexHighlight {
    /// `L_lm` to [`HIGHLIGHT_BANDS`].
    pub radiance: ShRgb,
    /// Per material, its glossy lobe to [`HIGHLIGHT_BANDS`] (`None` for Lambert).
    pub lobes: Vec<Option<crate::prt::GlossyLobe>>,
}

impl NormalMapFrame {
    /// The materials' maps for the viewport; a map of another size than the first mapped
    /// material's is left out, and `notes` says so as `(node, why)`.
    /// `per_vertex`: the mode shades the environment's light per vertex.
    pub fn new(
        materials: &[FrameMaterial],
        transported: Option<&ShRgb>,
        per_vertex: bool,
        notes: &mut Vec<(String, String)>,
    ) -> Self {
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
        let vertex_highlight = transported.filter(|_| per_vertex && mapped).map(|light| VertexHighlight {
            radiance: light.truncated(HIGHLIGHT_BANDS),
            lobes: frame_materials.iter().map(|m| crate::prt::glossy_lobe(&m.material, HIGHLIGHT_BANDS)).collect(),
        });
        Self { materials, vertex_diffuse_scale, vertex_highlight }
    }
}

/// How surfaces are lit: one variant per relighting mode.
#[derive(Clone, Debug)]
pub enum Surfaces {
    Irradiance(IrradianceSurfaces),
    Prt(PrtSurfaces),
    Wavelet(Box<WaveletSurfaces>),
    Rsl(RslSurfaces),
}

/// `sh_irradiance`: unshadowed diffuse light per pixel (Sun 2008 eq. 2.20).
#[derive(Clone, Debug)]
pub struct IrradianceSurfaces {
    /// `E_lm = Â_l L_lm` on at most [`IRRADIANCE_BANDS`] bands (none without an environment).
    pub irradiance: Option<ShRgb>,
    /// Per material: diffuse albedo.
    pub albedo: Vec<[f64; 3]>,
}

impl IrradianceSurfaces {
    /// `light` is the environment's SH radiance; in fog, surfaces see it through the medium.
    pub fn new(light: Option<&ShRgb>, fog: Option<&FoggedEnvironment>, materials: &[FrameMaterial]) -> Self {
        let irradiance = light.map(|light| fog.map_or(light, |f| &f.fogged).irradiance().truncated(IRRADIANCE_BANDS));
        Self { irradiance, albedo: materials.iter().map(|m| m.material.albedo).collect() }
    }
}

/// `sh_prt`: shadowed diffuse transfer and glossy lobes on shadowed incident light, per vertex.
#[derive(Clone, Debug)]
pub struct PrtSurfaces {
    /// [`crate::transport::ShTransport`] and [`crate::prt::IncidentSh`] per vertex (or
    /// [`crate::adaptive_sh::AdaptiveIncident`]: read it with [`incident_sh`]; its bands may
    /// be fewer than the transport's).
    pub transport: Keyed,
    pub incident: Keyed,
    /// The light the diffuse transfer sees (through fog when there is one), if any.
    pub light: Option<ShRgb>,
    pub albedo: Vec<[f64; 3]>,
    /// Per material: its glossy lobe, its weight scaled by what reaches surfaces through fog.
    pub glossy: Vec<Option<crate::prt::GlossyLobe>>,
}

impl PrtSurfaces {
    /// Checks that the transport covers the scene's `vertices`. In fog the diffuse transfer
    /// sees the fogged environment (Sun 2008 sec. 3.6.5); the glossy lobes read per-vertex
    /// incident light computed without fog, so they get only its attenuation.
    pub fn new(
        transport: Keyed,
        incident: Keyed,
        light: Option<&ShRgb>,
        fog: Option<&FoggedEnvironment>,
        materials: &[FrameMaterial],
        lobes: Vec<Option<crate::prt::GlossyLobe>>,
        vertices: usize,
    ) -> Result<Self, String> {
        let t = transport.value.expect::<crate::transport::ShTransport>().map_err(|e| e.to_string())?;
        let r = incident_sh(&incident.value)?;
        let n = t.bands * t.bands;
        let ni = r.bands * r.bands;
        if t.transfer.len() != vertices * n || (!r.coeffs.is_empty() && r.coeffs.len() != vertices * ni * 3) {
            return Err(format!("the transport has {} receivers for {vertices} vertices", t.transfer.len() / n.max(1)));
        }
        let attenuation = fog.map_or([1.0; 3], |f| f.fog.attenuation);
        let glossy = lobes
            .into_iter()
            .map(|lobe| {
                lobe.filter(|l| !l.factors.is_empty()).map(|mut l| {
                    l.weight = std::array::from_fn(|c| l.weight[c] * attenuation[c]);
                    l
                })
            })
            .collect();
        Ok(Self {
            transport,
            incident,
            light: light.map(|l| fog.map_or(l, |f| &f.fogged).clone()),
            albedo: materials.iter().map(|m| m.material.albedo).collect(),
            glossy,
        })
    }
}

/// Per-vertex incident radiance from `incident_sh` or, in `sh_adaptive`, `adaptive_incident`.
pub fn incident_sh(value: &crate::engine::StageValue) -> Result<&crate::prt::IncidentSh, String> {
    match value.get::<crate::adaptive_sh::AdaptiveIncident>() {
        Some(a) => Ok(&a.incident),
        None => value.expect::<crate::prt::IncidentSh>().map_err(|e| e.to_string()),
    }
}

/// What the wavelet modes multiply into `P_c = ΔΩ_c L_c V_c`: per-vertex visibility cells and
/// frames, and the environment with its rotation. None of it changes with the rotation but
/// the rotation itself, so a renderer rebuilds `P` from a uniform.
#[derive(Clone, Debug)]
pub struct WaveletLighting {
    /// [`crate::triple_product::LocalVisibility`] per vertex.
    pub visibility: Keyed,
    /// [`crate::transport::Receivers`]: the vertices' frames.
    pub receivers: Keyed,
    /// The unrotated environment prefiltered for the cells ([`crate::triple_product::prefiltered`]).
    pub environment: Keyed,
    /// `R`: the lit world sees `L(R⁻¹ d)`.
    pub rotation: glam::DMat3,
}

/// One set of receivers the viewport lights on the GPU: each one's frame and visibility cells.
#[derive(Clone, Debug)]
pub struct WaveletReceivers {
    pub key: Key,
    /// Per receiver `[t, 0]` then `[n, 0]`: its frame `[t, n × t, n]`.
    pub frames: Arc<Vec<[f32; 4]>>,
    /// [`crate::triple_product::LocalVisibility`], or [`crate::triple_product::TexelVisibility`]
    /// (which holds its receivers too).
    pub visibility: Keyed,
    /// [`crate::transport::Receivers`] for vertices; for texels the same as `visibility`.
    source: Keyed,
}

impl WaveletReceivers {
    fn new(source: Keyed, visibility: Keyed) -> Result<Self, String> {
        let mut set =
            Self { key: source.key ^ visibility.key.rotate_left(17), frames: Arc::default(), visibility, source };
        let receivers = set.receivers()?;
        let frames = (0..receivers.len())
            .flat_map(|i| {
                let f = receivers.frame(i);
                [f.x_axis, f.z_axis].map(|a| [a.x as f32, a.y as f32, a.z as f32, 0.0])
            })
            .collect();
        set.frames = Arc::new(frames);
        Ok(set)
    }

    /// The receivers whose frames these are.
    pub fn receivers(&self) -> Result<&crate::transport::Receivers, String> {
        if let Some(t) = self.source.value.get::<crate::triple_product::TexelVisibility>() {
            return Ok(&t.receivers);
        }
        self.source.value.expect::<crate::transport::Receivers>().map_err(|e| e.to_string())
    }

    /// The visibility cells, whichever stage made them.
    pub fn cells(&self) -> Result<&crate::triple_product::LocalVisibility, String> {
        use crate::triple_product::{LocalVisibility, TexelVisibility};
        if let Some(t) = self.visibility.value.get::<TexelVisibility>() {
            return Ok(&t.visibility);
        }
        self.visibility.value.expect::<LocalVisibility>().map_err(|e| e.to_string())
    }
}

/// The wavelet modes: the local-frame triple product `B = albedo Σ P_c D_c + specular Σ P_c
/// S_c(ω_o)` per vertex, and per texel on meshes with a visibility texture (`wavelet_pixel`).
/// `P` and the view-independent diffuse sum `E = Σ P_c D_c` are rebuilt only when the lighting
/// or visibility change (a GPU kernel; [`Self::cpu_products`] is its CPU twin).
#[derive(Clone, Debug)]
pub struct WaveletSurfaces {
    /// Changes whenever any buffer below but the environment does.
    pub key: Key,
    pub cells: usize,
    pub vertices: WaveletReceivers,
    /// `wavelet_pixel`: every texel slot of the visibility textures when it matches `cells`.
    pub texels: Option<WaveletReceivers>,
    /// Texels per side of the visibility textures.
    pub texel_size: usize,
    /// [`crate::cubemap::CubeMap`], prefiltered for the cells.
    pub environment: Keyed,
    /// `R`: the lit world sees `L(R⁻¹ d)`.
    pub rotation: glam::DMat3,
    /// Per cell its sub-cell samples `[direction in the local frame, solid angle]`, the same
    /// count per cell ([`crate::triple_product::CellGrid::samples`]).
    pub cell_samples: Arc<Vec<[f32; 4]>>,
    /// `D_c`, shared by all materials.
    pub diffuse_table: Arc<Vec<f32>>,
    /// Every material's `S_c(ω_o)` table coarsened to `cells`, zeros without a lobe; each
    /// [`Self::specular_stride`] long.
    pub specular_tables: Arc<Vec<f32>>,
    /// Per material and patch of the outgoing grid, `[first, count]` into `specular_cells`:
    /// the cells its glossy sum reads ([`crate::triple_product::significant_cells`]).
    pub specular_ranges: Arc<Vec<[u32; 2]>>,
    pub specular_cells: Arc<Vec<u32>>,
    /// Per material: diffuse albedo and specular colour (`None` without a lobe), both scaled
    /// by what reaches surfaces through fog (fog adds its scattered light separately).
    pub albedo: Vec<[f64; 3]>,
    pub specular: Vec<Option<[f64; 3]>>,
    /// Per vertex: its mesh's texel layer, or -1.
    pub vertex_layers: Arc<Vec<i32>>,
    /// Detail terms each receiver keeps (0 without any glossy material) and their per-node
    /// weights ([`crate::triple_product::details`]).
    pub details: Arc<crate::triple_product::details::DetailWeights>,
    /// Per material its fine lobe table
    /// ([`crate::triple_product::BrdfTable::fine_specular`] at `cells`), empty without a lobe
    /// or detail terms; a renderer lays them one after another.
    pub fine_specular_tables: Vec<Arc<Vec<half::f16>>>,
    /// Per material: where its fine table starts in that concatenation.
    pub fine_specular_offsets: Vec<u32>,
}

impl WaveletSurfaces {
    /// `tables` are the materials' [`crate::triple_product::BrdfTable`]s, one per material;
    /// each receiver keeps up to `details` detail terms.
    pub fn new(
        lighting: WaveletLighting,
        tables: &[Keyed],
        texels: Option<Keyed>,
        fog: Option<&FoggedEnvironment>,
        geometry: &Geometry,
        materials: &[FrameMaterial],
        details: usize,
    ) -> Result<Self, String> {
        use crate::triple_product::{BrdfTable, CellGrid, LocalVisibility, TexelVisibility};
        let visibility = lighting.visibility.value.expect::<LocalVisibility>().map_err(|e| e.to_string())?;
        let receivers = lighting.receivers.value.expect::<crate::transport::Receivers>().map_err(|e| e.to_string())?;
        let vertices = geometry.vertex_count();
        let cells = visibility.cells;
        if cells == 0 || visibility.receivers() != vertices || receivers.len() != vertices {
            return Err(format!(
                "the triple-product data covers {} receivers ({} frames) for {vertices} vertices",
                visibility.receivers(),
                receivers.len()
            ));
        }
        let grid = CellGrid::for_coefficients(cells)?;
        let mut coarse = Vec::new();
        let mut key =
            lighting.visibility.key ^ lighting.receivers.key.rotate_left(5) ^ geometry.meshes.key.rotate_left(3);
        for keyed in tables {
            let table = keyed.value.expect::<BrdfTable>().map_err(|e| e.to_string())?;
            coarse.push(table.coarsened(cells)?);
            key = key.rotate_left(7) ^ keyed.key;
        }
        let Some(first) = coarse.first() else {
            return Err("the wavelet modes need a material: link a BRDF editor to the Output".into());
        };
        let stride = Self::specular_stride(cells);
        let mut specular_tables = vec![0.0f32; stride * coarse.len()];
        for (i, t) in coarse.iter().enumerate() {
            if !t.specular.is_empty() {
                specular_tables[i * stride..(i + 1) * stride].copy_from_slice(&t.specular);
            }
        }
        let (mut specular_ranges, mut specular_cells) = (Vec::new(), Vec::new());
        for t in &coarse {
            let (ranges, cells) = if t.specular.is_empty() {
                (vec![[0, 0]; (crate::triple_product::THETA_STEPS - 1) * crate::triple_product::PHI_STEPS], Vec::new())
            } else {
                crate::triple_product::significant_cells(&t.specular, grid)
            };
            let offset = specular_cells.len() as u32;
            specular_ranges.extend(ranges.into_iter().map(|[first, count]| [first + offset, count]));
            specular_cells.extend(cells);
        }
        // Without any mesh that has a visibility texture there are no texels to light.
        let texels = texels
            .filter(|t| t.value.get::<TexelVisibility>().is_some_and(|t| t.visibility.cells == cells && t.slots() > 0));
        let texel_data = texels.as_ref().and_then(|t| t.value.get::<TexelVisibility>());
        let mut vertex_layers = Vec::with_capacity(vertices);
        if let Some(set) = geometry.meshes.value.get::<crate::mesh::MeshSet>() {
            for (m, mesh) in set.meshes.iter().enumerate() {
                let layer = texel_data.and_then(|t| t.mesh_layers.get(m)).copied().unwrap_or(-1);
                vertex_layers.extend(std::iter::repeat_n(layer, mesh.positions.len()));
            }
        }
        let texel_size = texel_data.map_or(0, |t| t.size);
        let texels = match texels {
            Some(keyed) => {
                key = key.rotate_left(11) ^ keyed.key;
                Some(WaveletReceivers::new(keyed.clone(), keyed)?)
            }
            None => None,
        };
        let attenuation = fog.map_or([1.0; 3], |f| f.fog.attenuation);
        let scale = |c: [f64; 3]| std::array::from_fn(|i| c[i] * attenuation[i]);
        let specular: Vec<Option<[f64; 3]>> =
            coarse.iter().map(|t| (!t.specular.is_empty()).then(|| scale(t.specular_color.map(f64::from)))).collect();
        let weighted: Vec<(&BrdfTable, f64)> =
            coarse.iter().zip(&specular).map(|(t, s)| (t, s.map_or(0.0, |s| s[0].max(s[1]).max(s[2])))).collect();
        let details = crate::triple_product::details::DetailWeights::new(grid, &weighted, details);
        let (mut fine_specular_tables, mut fine_specular_offsets, mut offset) = (Vec::new(), Vec::new(), 0);
        for t in &coarse {
            let table = if details.kept > 0 { t.fine_specular.clone() } else { Arc::default() };
            fine_specular_offsets.push(offset as u32);
            offset += table.len();
            fine_specular_tables.push(table);
        }
        if details.kept > 0 {
            key = key.rotate_left(19) ^ details.kept as Key;
        }
        Ok(Self {
            key,
            cells,
            vertices: WaveletReceivers::new(lighting.receivers, lighting.visibility)?,
            texels,
            texel_size,
            environment: lighting.environment,
            rotation: lighting.rotation,
            cell_samples: Arc::new(
                grid.samples.iter().flatten().map(|(d, w)| [d.x as f32, d.y as f32, d.z as f32, *w as f32]).collect(),
            ),
            diffuse_table: Arc::new(first.diffuse.clone()),
            specular_tables: Arc::new(specular_tables),
            specular_ranges: Arc::new(specular_ranges),
            specular_cells: Arc::new(specular_cells),
            albedo: materials.iter().map(|m| scale(m.material.albedo)).collect(),
            specular,
            vertex_layers: Arc::new(vertex_layers),
            details: Arc::new(details),
            fine_specular_tables,
            fine_specular_offsets,
        })
    }

    /// Rows of `R⁻¹`, in f32 (what the relight kernel reads).
    pub fn inverse_rotation(&self) -> [[f32; 3]; 3] {
        let inverse = self.rotation.transpose();
        [inverse.row(0), inverse.row(1), inverse.row(2)].map(|r| r.as_vec3().to_array())
    }

    /// What the relit products depend on besides the lighting: the receiver sets.
    pub fn receivers_key(&self) -> Key {
        self.vertices.key
            ^ self.texels.as_ref().map_or(0, |t| t.key.rotate_left(13))
            ^ self.cells as Key
            ^ (self.details.kept as Key).rotate_left(29)
    }

    /// What the kept detail terms depend on besides the lighting and receivers: the
    /// materials' weights (a BRDF edit moves them, and so relights).
    pub fn details_key(&self) -> Key {
        self.details.squared.iter().fold(self.details.kept as Key, |k, w| k.rotate_left(7) ^ Key::from(w.to_bits()))
    }

    /// `P` per vertex on the CPU (the GPU kernel's twin; the bake's vertex light, which reads
    /// the diffuse transfer alone and so keeps no detail terms). Big meshes read the lighting
    /// from a pre-rotated [`crate::triple_product::FrameTable`].
    pub fn cpu_products(&self) -> Result<crate::triple_product::LocalProducts, String> {
        let plain = Self { details: Arc::default(), ..self.clone() };
        let table = plain.frame_table_for(&plain.vertices)?;
        Ok(plain.cpu_products_of(&plain.vertices, table.as_ref())?.0)
    }

    /// The pre-rotated lighting table when `set` has more receivers than
    /// [`crate::triple_product::FRAME_TABLE_THRESHOLD`] (built once per environment).
    pub fn frame_table_for(&self, set: &WaveletReceivers) -> Result<Option<crate::triple_product::FrameTable>, String> {
        use crate::triple_product::{CellGrid, FRAME_TABLE_THRESHOLD, FrameTable};
        // Detail terms sample the lighting directly.
        if set.frames.len() / 2 <= FRAME_TABLE_THRESHOLD || self.details.kept > 0 {
            return Ok(None);
        }
        let environment = self.environment.value.expect::<crate::cubemap::CubeMap>().map_err(|e| e.to_string())?;
        Ok(Some(FrameTable::build(CellGrid::for_coefficients(self.cells)?, environment)))
    }

    /// `P` and the kept detail terms of one receiver set on the CPU, with the lighting from
    /// `table` when given (and no details are kept).
    pub fn cpu_products_of(
        &self,
        set: &WaveletReceivers,
        table: Option<&crate::triple_product::FrameTable>,
    ) -> Result<(crate::triple_product::LocalProducts, crate::triple_product::details::LocalDetails), String> {
        use crate::triple_product::{CellGrid, Lighting, local_products_with_details};
        let grid = CellGrid::for_coefficients(self.cells)?;
        let environment = self.environment.value.expect::<crate::cubemap::CubeMap>().map_err(|e| e.to_string())?;
        let lighting = Lighting { environment, rotation: self.rotation, table };
        let cancel = crate::engine::CancelToken::default();
        local_products_with_details(grid, &lighting, set.receivers()?, set.cells()?, &self.details, &cancel)
            .map_err(|e| e.to_string())
    }

    /// The CPU relight of one receiver set from its pre-rotated `table`, in one pass: its
    /// products packed by `pack` and its diffuse transfer (the frame table is only built where
    /// no detail terms are kept).
    pub fn cpu_packed_products_of(
        &self,
        set: &WaveletReceivers,
        table: &crate::triple_product::FrameTable,
        pack: impl Fn([f32; 3]) -> u32 + Sync,
    ) -> Result<(Vec<u32>, Vec<[f32; 4]>), String> {
        let cancel = crate::engine::CancelToken::default();
        let (receivers, visibility) = (set.receivers()?, set.cells()?);
        crate::triple_product::table_products_packed(
            table,
            self.rotation,
            receivers,
            visibility,
            &self.diffuse_table,
            pack,
            &cancel,
        )
        .map_err(|e| e.to_string())
    }

    /// Floats of one material's specular table.
    pub fn specular_stride(cells: usize) -> usize {
        crate::triple_product::THETA_STEPS * crate::triple_product::PHI_STEPS * cells
    }
}

/// `rsl`: square lights per vertex (Xu et al. 2006 Eq. 5). The shader sums `I Ω ρ̄ V̄` over
/// the lights with `ρ̄` from the materials' summed-area tables at the vertex's view; `V̄`
/// comes per vertex and light from the `rsl_visibility` stage.
#[derive(Clone, Debug)]
pub struct RslSurfaces {
    /// Changes whenever any buffer below does.
    pub key: Key,
    /// Per light, world frame: `[direction xyz, solid angle, intensity rgb, 0]`.
    pub lights: Arc<Vec<[f32; 8]>>,
    /// [`crate::rsl::shade::LightVisibility`]: `V̄` per vertex and light.
    pub visibility: Keyed,
    /// Texels per side of every table.
    pub table_size: usize,
    /// Every material's corner-stored SATs, concatenated: `cos θ/π`, then one `lobe · cos θ`
    /// table per view slice, each `(table_size + 1)²`.
    pub tables: Arc<Vec<f32>>,
    /// Per material: `[first float, view grid (0 none, 1 isotropic, 2 anisotropic), slices per
    /// side or θ₀ slices, 0]`.
    pub layouts: Vec<[u32; 4]>,
    /// Per material: diffuse albedo and specular colour, scaled by what reaches surfaces
    /// through fog.
    pub albedo: Vec<[f64; 3]>,
    pub specular: Vec<[f64; 3]>,
}

impl RslSurfaces {
    /// `tables` are the materials' [`crate::rsl::brdf_sat::BrdfSat`]s, one per material.
    pub fn new(
        lights: &crate::rsl::WorldLights,
        lights_key: Key,
        visibility: Keyed,
        tables: &[Keyed],
        fog: Option<&FoggedEnvironment>,
        geometry: &Geometry,
    ) -> Result<Self, String> {
        use crate::rsl::brdf_sat::{BrdfSat, ViewGrid};
        let v = visibility.value.expect::<crate::rsl::shade::LightVisibility>().map_err(|e| e.to_string())?;
        let vertices = geometry.vertex_count();
        if v.vertices != vertices || v.lights != lights.lights.len() {
            return Err(format!(
                "the square-light visibility covers {} vertices × {} lights for {vertices} vertices × {} lights",
                v.vertices,
                v.lights,
                lights.lights.len()
            ));
        }
        let mut key = visibility.key ^ lights_key.rotate_left(5) ^ geometry.meshes.key.rotate_left(3);
        let (mut data, mut layouts, mut albedo, mut specular) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let attenuation = fog.map_or([1.0; 3], |f| f.fog.attenuation);
        let scale = |c: [f64; 3]| std::array::from_fn(|i| c[i] * attenuation[i]);
        let mut size = None;
        for keyed in tables {
            let sat = keyed.value.expect::<BrdfSat>().map_err(|e| e.to_string())?;
            if *size.get_or_insert(sat.size) != sat.size {
                return Err("the materials' summed-area tables differ in resolution".into());
            }
            key = key.rotate_left(7) ^ keyed.key;
            let (kind, slices) = match (sat.lobes.is_empty(), sat.views) {
                (true, _) => (0, 0),
                (false, ViewGrid::Isotropic { slices }) => (1, slices),
                (false, ViewGrid::Anisotropic { size }) => (2, size),
            };
            layouts.push([data.len() as u32, kind, slices as u32, 0]);
            for table in std::iter::once(&sat.cosine).chain(&sat.lobes) {
                data.extend(table.corners().iter().map(|&c| c as f32));
            }
            albedo.push(scale(sat.diffuse));
            specular.push(scale(sat.specular));
        }
        let table_size = size.ok_or("the rsl mode needs a material: link a BRDF editor to the Output")?;
        let lights = lights
            .lights
            .iter()
            .map(|l| {
                let [x, y, z] = l.direction.map(|c| c as f32);
                let [r, g, b] = l.intensity.map(|c| c as f32);
                [x, y, z, l.solid_angle as f32, r, g, b, 0.0]
            })
            .collect();
        Ok(Self {
            key,
            lights: Arc::new(lights),
            visibility,
            table_size,
            tables: Arc::new(data),
            layouts,
            albedo,
            specular,
        })
    }
}

/// Painted area lights (Sun 2008 §4.5): diffuse light per vertex, drawn over the mode's
/// surfaces as `albedo · colour / π · E`, plus their glossy highlights toward the view (§4.9).
#[derive(Clone, Debug)]
pub struct AreaLightFrame {
    /// [`crate::kinds::output_area::AreaIrradiance`]: `E` per vertex from every linked light.
    pub irradiance: Keyed,
    /// [`crate::kinds::output_area::AreaHighlights`]: reflected radiance per vertex (none, or
    /// empty, without a glossy material).
    pub highlights: Option<Keyed>,
    /// Per material: diffuse albedo.
    pub albedo: Vec<[f64; 3]>,
    /// The lights as the reference samples them.
    pub emitters: Vec<crate::reference::AreaEmitter>,
}

impl AreaLightFrame {
    /// Checks that the irradiance covers the scene's `vertices`.
    pub fn new(
        irradiance: Keyed,
        highlights: Option<Keyed>,
        emitters: Vec<crate::reference::AreaEmitter>,
        materials: &[FrameMaterial],
        vertices: usize,
    ) -> Result<Self, String> {
        let e = irradiance.value.expect::<crate::kinds::output_area::AreaIrradiance>().map_err(|e| e.to_string())?;
        if e.irradiance.len() != vertices {
            return Err(format!("the area lights cover {} receivers for {vertices} vertices", e.irradiance.len()));
        }
        if let Some(h) = &highlights {
            let h = h.value.expect::<crate::kinds::output_area::AreaHighlights>().map_err(|e| e.to_string())?;
            if !h.radiance.is_empty() && h.radiance.len() != vertices {
                return Err(format!("the area-light highlights cover {} of {vertices} vertices", h.radiance.len()));
            }
        }
        Ok(Self { irradiance, highlights, albedo: materials.iter().map(|m| m.material.albedo).collect(), emitters })
    }
}

/// Point lights and the participating medium (Sun 2008 ch. 3), shaded with every surface.
#[derive(Clone, Debug, Default)]
pub struct MediumFrame {
    /// At most [`MAX_LIGHTS`].
    pub lights: Vec<PointLight>,
    /// Per material: its Phong-equivalent lobe `(weight per channel, exponent)` for point
    /// lights and light scattered onto surfaces (eq. 3.28; `None` for Lambert).
    pub surface_lobes: Vec<Option<([f64; 3], f64)>>,
    pub fog: Option<FogFrame>,
}

impl MediumFrame {
    pub fn new(lights: Vec<PointLight>, materials: &[FrameMaterial], fog: Option<FogFrame>) -> Self {
        let surface_lobes = materials
            .iter()
            .map(|m| {
                let brdf = crate::brdf::Brdf::from_material(&m.material);
                brdf.equivalent_phong_exponent().map(|n| ((brdf.specular * brdf.f0).to_array(), n.max(1.0)))
            })
            .collect();
        Self { lights, surface_lobes, fog }
    }
}

/// A homogeneous medium for one frame: coefficients, tables, and the environment through it.
#[derive(Clone, Debug)]
pub struct FogFrame {
    /// Scattering coefficient per channel, 1/m.
    pub beta: [f64; 3],
    /// Normalised phase polynomial weights `W_k` (eq. 3.18), one per `F^k` table.
    pub phase: Vec<f64>,
    /// `F^k` tables (`Vec<FTable>`) and the `G_n` ladder (`PhongGTables`).
    pub f_tables: Keyed,
    pub g_tables: Keyed,
    /// With an environment linked: its light through the medium (sec. 3.6.4).
    pub environment: Option<FoggedEnvironment>,
    /// Whether surfaces get the environment's scattered irradiance from the medium pass: the
    /// wavelet modes cannot convolve their all-frequency light, the SH modes already see it
    /// in their fogged light.
    pub scatter_onto_surfaces: bool,
}

impl FrameInputs {
    /// The frame material of mesh `i`.
    pub fn mesh_frame_material(&self, i: usize) -> &FrameMaterial {
        &self.materials[self.geometry.mesh_materials.get(i).copied().unwrap_or(0) as usize]
    }

    /// The material of mesh `i`.
    pub fn mesh_material(&self, i: usize) -> &Material {
        &self.mesh_frame_material(i).material
    }

    /// The Monte Carlo reference of this frame (see [`crate::reference`]).
    pub fn render_reference(
        &self,
        camera: &crate::reference::PinholeCamera,
        size: (usize, usize),
        seed: u64,
        cancel: &crate::engine::CancelToken,
        progress: &(dyn Fn(f64) + Sync),
    ) -> Result<crate::reference::HdrImage, String> {
        let Some(scene) = self.ray_scene.as_ref().and_then(|r| r.value.get::<crate::raycast::RayScene>()) else {
            return Err("the scene's ray_scene stage was not evaluated".into());
        };
        let meshes = self.geometry.meshes.value.expect::<crate::mesh::MeshSet>().map_err(|e| e.to_string())?;
        let black = crate::cubemap::CubeMap::new(1, vec![[0.0; 3]; 6]);
        let environment = match &self.background.radiance {
            Some(r) => r.value.expect::<crate::cubemap::CubeMap>().map_err(|e| e.to_string())?,
            None => &black,
        };
        let normal_maps: Vec<Option<(&crate::normal_filtering::NormalMap, f64)>> = (0..meshes.meshes.len())
            .map(|i| {
                let detail = self.mesh_frame_material(i).normal.as_ref()?;
                let map = detail.map.value.get::<crate::normal_filtering::NormalMap>()?;
                (!map.normals.is_empty()).then_some((map, detail.settings.tiling))
            })
            .collect();
        let rs = crate::reference::ReferenceScene {
            scene,
            meshes,
            brdfs: (0..meshes.meshes.len()).map(|i| crate::brdf::Brdf::from_material(self.mesh_material(i))).collect(),
            environment,
            background: self.settings.background,
            // Blocker spheres are opaque to the reference's rays; a set faded to strength 0
            // casts nothing (fractional strengths are an artistic fade it does not model).
            blockers: self.blockers.as_ref().filter(|b| b.strength > 0.0).map_or(&[], |b| b.blockers.as_slice()),
            area_lights: self.area_lights.as_ref().map_or(&[], |a| a.emitters.as_slice()),
            normal_maps: &normal_maps,
        };
        crate::reference::render(&rs, camera, size, self.settings.reference_samples, seed, cancel, progress)
            .map_err(|e| e.to_string())
    }

    /// The mesh seen through image point `(x, y)` (pixels, `y` down) of a `width × height` view:
    /// its index in the scene's meshes, or `None` for the background.
    pub fn pick(
        &self,
        camera: &crate::reference::PinholeCamera,
        (x, y): (f64, f64),
        (width, height): (usize, usize),
    ) -> Option<usize> {
        let (Some(scene), Some(meshes)) = (
            self.ray_scene.as_ref().and_then(|r| r.value.get::<crate::raycast::RayScene>()),
            self.geometry.meshes.value.get::<crate::mesh::MeshSet>(),
        ) else {
            return None;
        };
        let dir = camera.ray(x, y, width.max(1), height.max(1));
        let (_, triangle) = scene.closest(camera.position.as_vec3a(), dir.as_vec3a())?;
        meshes.mesh_of_triangle(triangle as usize)
    }
}
