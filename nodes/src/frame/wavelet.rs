//! The wavelet modes' surfaces (Ma et al.; Sun 2008 ch. 4).

use super::*;

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
    /// Every receiver set relit on the CPU, where the frame was asked for it
    /// ([`super::FrameNeeds::relight_on_cpu`]): a viewport uploads these instead of running
    /// the relight kernel.
    pub relit: Option<RelitSets>,
}

/// The receiver sets relit by the engine ([`crate::triple_product::relight::RelitReceivers`]
/// each, from the Output's `wavelet_*relit` stages).
#[derive(Clone, Debug)]
pub struct RelitSets {
    pub vertices: Keyed,
    /// With texels lit ([`WaveletSurfaces::texels`]).
    pub texels: Option<Keyed>,
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
        let details = crate::triple_product::relight::material_detail_weights(grid, &coarse, attenuation, details);
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
            relit: None,
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
        let cancel = crate::engine::CancelToken::default();
        Ok(plain.cpu_products_of(&plain.vertices, table.as_ref(), &cancel)?.0)
    }

    /// The relight's inputs besides the receivers, or an error naming a missing one.
    pub fn relight<R>(
        &self,
        with: impl FnOnce(&crate::triple_product::relight::Relight) -> Result<R, String>,
    ) -> Result<R, String> {
        let grid = crate::triple_product::CellGrid::for_coefficients(self.cells)?;
        let environment = self.environment.value.expect::<crate::cubemap::CubeMap>().map_err(|e| e.to_string())?;
        with(&crate::triple_product::relight::Relight {
            grid,
            environment,
            rotation: self.rotation,
            diffuse_table: &self.diffuse_table,
            details: &self.details,
        })
    }

    /// The pre-rotated lighting table when `set` reads one
    /// ([`crate::triple_product::relight::Relight::uses_frame_table`]; built once per
    /// environment).
    pub fn frame_table_for(&self, set: &WaveletReceivers) -> Result<Option<crate::triple_product::FrameTable>, String> {
        self.relight(|r| {
            Ok(r.uses_frame_table(set.frames.len() / 2)
                .then(|| crate::triple_product::FrameTable::build(r.grid, r.environment)))
        })
    }

    /// `P` and the kept detail terms of one receiver set on the CPU, with the lighting from
    /// `table` when given (and no details are kept).
    pub fn cpu_products_of(
        &self,
        set: &WaveletReceivers,
        table: Option<&crate::triple_product::FrameTable>,
        cancel: &crate::engine::CancelToken,
    ) -> Result<(crate::triple_product::LocalProducts, crate::triple_product::details::LocalDetails), String> {
        self.relight(|r| r.products(set.receivers()?, set.cells()?, table, cancel).map_err(|e| e.to_string()))
    }

    /// Floats of one material's specular table.
    pub fn specular_stride(cells: usize) -> usize {
        crate::triple_product::THETA_STEPS * crate::triple_product::PHI_STEPS * cells
    }
}

/// `wavelet_vertex`, and `wavelet_pixel` (`texels`: meshes with a visibility texture lit per
/// texel) as frame parts: the visibility cells, the prefiltered environment and its rotation,
/// each material's local-frame table; on a CPU viewport, the receivers relit by the engine.
pub(super) struct Wavelet {
    pub texels: bool,
}

impl Wavelet {
    /// The Output stage of the prefiltered environment the cells are lit by.
    fn environment(separate_sun: bool) -> &'static str {
        if separate_sun { "wavelet_residual_environment" } else { "wavelet_environment" }
    }
}

impl ModeFrame for Wavelet {
    fn material_stages(&self) -> &'static [&'static str] {
        &["local_table"]
    }

    fn needs_material(&self) -> bool {
        true
    }

    fn stages(&self, linked: &Linked) -> Vec<StageRef> {
        let output = linked.output;
        let mut stages = vec![
            StageRef::new(output, "local_visibility"),
            StageRef::new(output, Self::environment(linked.separate_sun)),
        ];
        if let Some(environment) = &linked.environment {
            stages.push(StageRef::new(environment, "rotation"));
        }
        if let Some(scene) = &linked.scene {
            stages.push(StageRef::new(scene, "receivers"));
        }
        if self.texels {
            stages.push(StageRef::new(output, "texel_visibility"));
        }
        stages
    }

    fn cpu_relight_stages(&self, linked: &Linked) -> Vec<StageRef> {
        use crate::kinds::output::relight::stage_name;
        let sets: &[bool] = if self.texels { &[false, true] } else { &[false] };
        sets.iter().map(|texels| StageRef::new(linked.output, stage_name(*texels, linked.separate_sun))).collect()
    }

    fn surfaces(&self, g: &Gather, parts: &MaterialParts, inputs: &SurfaceInputs) -> Result<Surfaces, String> {
        let output = g.output;
        // Without an environment there is no lighting to multiply in: surfaces get no
        // environment light.
        let environment = g.keyed(output, Self::environment(g.separate_sun))?;
        if environment.value.get::<crate::cubemap::CubeMap>().is_some_and(|c| c.size == 0) {
            return super::prt::Irradiance.surfaces(g, parts, inputs);
        }
        let node = g.upstream("environment").ok_or("the wavelet modes need an environment")?;
        let scene = g.upstream("scene").ok_or("the wavelet modes need a scene")?;
        let rotation = g.keyed(&node, "rotation")?;
        let lighting = WaveletLighting {
            visibility: g.keyed(output, "local_visibility")?,
            receivers: g.keyed(&scene, "receivers")?,
            environment,
            rotation: *rotation.value.expect::<glam::DMat3>().map_err(|e| e.to_string())?,
        };
        let texels = if self.texels { Some(g.keyed(output, "texel_visibility")?) } else { None };
        let tables: Vec<Keyed> = parts.mode_stages.iter().flatten().cloned().collect();
        let details = g.settings.wavelet_details;
        let (fogged, geometry) = (inputs.fogged, inputs.geometry);
        let mut surfaces =
            WaveletSurfaces::new(lighting, &tables, texels, fogged, geometry, &parts.materials, details)?;
        surfaces.relit = relit(g, surfaces.texels.is_some());
        Ok(Surfaces::Wavelet(Box::new(surfaces)))
    }
}

/// The engine's CPU relight of the receiver sets, where the request asked for it and it
/// finished; all of them or none (a failed texel relight leaves the vertices to the kernel
/// too: the kernel relights every set in one dispatch, and the failure is reported).
fn relit(g: &Gather, texels: bool) -> Option<RelitSets> {
    use crate::kinds::output::relight::stage_name;
    let done = |texels: bool| g.keyed(g.output, stage_name(texels, g.separate_sun)).ok();
    let texels = match texels {
        true => Some(done(true)?),
        false => None,
    };
    Some(RelitSets { vertices: done(false)?, texels })
}
