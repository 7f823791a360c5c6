//! The wavelet modes: the local-frame triple product per vertex, and per pixel from the
//! visibility textures' texels (`nodes/src/triple_product.rs`, Ma et al. eq. 7).
//!
//! The receivers' visibility cells and frames stay on the GPU. When the lighting changes, a
//! compute kernel (`wavelet_relight.wgsl`) rebuilds each receiver's products `P` and diffuse
//! transfer `E` from the prefiltered environment; a rotation only changes its uniform, and
//! camera moves rebuild nothing.

use super::geometry::GeometryBuffers;
use super::{Draw, Pass, PassSetup, entry, stage_value, storage_buffer, uniform_buffer, vec3s, write_uniform};
use crate::shaders::Shader;
use crate::{GpuContext, RenderError};
use lightloom_nodes::cubemap::CubeMap;
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{MAX_MATERIALS, RelitSets, WaveletReceivers, WaveletSurfaces};
use lightloom_nodes::triple_product::relight::RelitReceivers;
use lightloom_nodes::triple_product::{PHI_STEPS, THETA_STEPS};

pub(crate) const SHADER: Shader = Shader::mesh("mesh_wavelet", "WAVELET");
pub(crate) const RELIGHT_SHADER: Shader =
    Shader::file("wavelet-relight", crate::shaders::source!("wavelet_relight.wgsl"));

/// Invocations per workgroup of the relight kernel.
const WORKGROUP: u32 = 64;

/// `mesh_wavelet.wgsl` `WaveletParams`.
#[derive(encase::ShaderType)]
pub(crate) struct WaveletParams {
    pub(crate) cells: u32,
    /// Floats of one material's specular table.
    pub(crate) specular_stride: u32,
    pub(crate) theta_steps: u32,
    pub(crate) phi_steps: u32,
    /// 1 when per-texel data is bound.
    pub(crate) texels_bound: u32,
    pub(crate) texel_size: u32,
    /// Detail nodes kept per receiver.
    pub(crate) details_kept: u32,
    pub(crate) materials: [WaveletMaterial; MAX_MATERIALS],
}

/// `mesh_wavelet.wgsl` `WaveletMaterial`.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct WaveletMaterial {
    pub(crate) albedo: glam::Vec3,
    /// 1 with a specular lobe.
    pub(crate) glossy: u32,
    pub(crate) specular: glam::Vec3,
    /// Where its fine lobe table starts.
    pub(crate) fine_offset: u32,
}

/// `wavelet_relight.wgsl` `RelightParams`.
#[derive(encase::ShaderType)]
pub(crate) struct RelightParams {
    /// `R⁻¹`.
    pub(crate) inverse_rotation: glam::Mat3,
    pub(crate) receivers: u32,
    pub(crate) cells: u32,
    pub(crate) samples_per_cell: u32,
    /// Texels per side of the environment's faces.
    pub(crate) face_size: u32,
    /// Receivers per row of workgroups.
    pub(crate) row_width: u32,
    /// Detail nodes kept per receiver.
    pub(crate) details_kept: u32,
}

/// One receiver set on the GPU (the vertices, or the texel slots): the kernel's inputs and
/// what it writes.
struct LitReceivers {
    count: u32,
    frames: wgpu::Buffer,
    visibility: wgpu::Buffer,
    products: wgpu::Buffer,
    irradiance: wgpu::Buffer,
    /// Five words per receiver and kept detail node (`triple_product::packing::detail_words`).
    details: wgpu::Buffer,
    /// Bytes the products, diffuse transfer and detail terms take (the buffers hold at least
    /// 16).
    sizes: [u64; 3],
    params: wgpu::Buffer,
}

impl LitReceivers {
    fn upload(gpu: &GpuContext, label: &str, receivers: &WaveletReceivers, kept: usize) -> Result<Self, RenderError> {
        let visibility = receivers.cells().map_err(RenderError::Invalid)?;
        let count = visibility.receivers();
        let limit = gpu.device.limits().max_storage_buffer_binding_size.min(gpu.device.limits().max_buffer_size);
        let bytes = (count * visibility.cells * 4) as u64;
        let detail_bytes = (count * kept * 20) as u64;
        if bytes > limit {
            return Err(RenderError::Invalid(format!(
                "the wavelet mode's {label} need {} MiB of products ({count} × {} cells) but this GPU binds at most {} \
                 MiB: use 80 coefficients, fewer vertices or a smaller visibility texture",
                bytes >> 20,
                visibility.cells,
                limit >> 20
            )));
        }
        if detail_bytes > limit {
            return Err(RenderError::Invalid(format!(
                "the wavelet mode's {label} need {} MiB of detail terms ({count} × {kept}) but this GPU binds at most {} \
                 MiB: use fewer wavelet detail terms, fewer vertices or a smaller visibility texture",
                detail_bytes >> 20,
                limit >> 20
            )));
        }
        // Two half floats per word (cell counts are even).
        let halves: Vec<u32> = visibility
            .values
            .chunks_exact(2)
            .map(|p| {
                u32::from(half::f16::from_f32(p[0]).to_bits()) | u32::from(half::f16::from_f32(p[1]).to_bits()) << 16
            })
            .collect();
        let output = |name: &str, size: u64| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(name),
                size: size.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        Ok(Self {
            count: count as u32,
            frames: storage_buffer(gpu, "wavelet-frames", &receivers.frames),
            visibility: storage_buffer(gpu, "wavelet-visibility", &halves),
            products: output("wavelet-products", bytes),
            irradiance: output("wavelet-irradiance", count as u64 * 16),
            details: output("wavelet-details", detail_bytes),
            sizes: [bytes, count as u64 * 16, detail_bytes],
            params: uniform_buffer::<RelightParams>(&gpu.device, "wavelet-relight-params"),
        })
    }
}

/// Where the wavelet modes' products are rebuilt when the lighting changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RelightOn {
    /// The compute kernel on a real GPU; the CPU twin on a CPU adapter (lavapipe), where it
    /// is faster than the kernel.
    Auto,
    /// The compute kernel (`wavelet_relight.wgsl`).
    Gpu,
    /// The engine's CPU relight ([`WaveletSurfaces::relit`], asked for with
    /// `FrameNeeds::relight_on_cpu`), uploaded; the kernel where a frame has none.
    Cpu,
}

impl RelightOn {
    /// `LIGHTLOOM_RELIGHT=gpu` or `cpu` (to compare the two); otherwise the device decides.
    pub fn from_env() -> Self {
        match std::env::var("LIGHTLOOM_RELIGHT").as_deref() {
            Ok("gpu") => Self::Gpu,
            Ok("cpu") => Self::Cpu,
            _ => Self::Auto,
        }
    }

    /// Whether relights run on the CPU on `gpu`'s adapter: what a frame for it asks the
    /// engine for (`FrameNeeds::relight_on_cpu`).
    pub fn on_cpu(self, gpu: &GpuContext) -> bool {
        match self {
            Self::Gpu => false,
            Self::Cpu => true,
            Self::Auto => gpu.adapter.get_info().device_type == wgpu::DeviceType::Cpu,
        }
    }
}

/// The receiver sets on the GPU and what lighting them reads besides the environment.
struct Receivers {
    key: Key,
    texel_size: Option<u32>,
    vertices: LitReceivers,
    texels: Option<LitReceivers>,
    cell_samples: wgpu::Buffer,
    /// `D_c` per cell, then the detail nodes' weights.
    cell_tables: wgpu::Buffer,
    details_key: Key,
}

/// The environment the kernel samples and its bind groups, one per receiver set.
struct Lit {
    environment_key: Key,
    bind_groups: Vec<(u32, wgpu::BindGroup)>,
}

/// The draw's bind group: the receivers' products and the materials' tables.
struct Bound {
    key: Key,
    bind_group: wgpu::BindGroup,
}

pub(crate) struct WaveletPass {
    layout: wgpu::BindGroupLayout,
    pipeline: super::SurfacePipelines,
    relight_layout: wgpu::BindGroupLayout,
    relight: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    relight_on: RelightOn,
    receivers: Option<Receivers>,
    lit: Option<Lit>,
    bound: Option<Bound>,
    /// The receivers' key, the environment's key, the rotation and the detail weights' key `P`
    /// was last built for.
    relit: Option<(Key, Key, [[f32; 3]; 3], Key)>,
}

impl WaveletPass {
    pub fn new(setup: &PassSetup) -> Self {
        use wgpu::ShaderStages as S;
        let layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("wavelet"),
            entries: &[
                entry::uniform(0, S::VERTEX_FRAGMENT),
                entry::storage(1, S::VERTEX),
                entry::storage(2, S::VERTEX),
                entry::storage(3, S::VERTEX_FRAGMENT),
                entry::storage(4, S::FRAGMENT),
                entry::storage(5, S::FRAGMENT),
                entry::storage(6, S::VERTEX),
                entry::storage(7, S::VERTEX_FRAGMENT),
                entry::storage(8, S::VERTEX_FRAGMENT),
                entry::storage(9, S::VERTEX),
                entry::storage(10, S::FRAGMENT),
                entry::storage(11, S::VERTEX_FRAGMENT),
            ],
        });
        let compute = S::COMPUTE;
        let relight_layout = setup.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("wavelet-relight"),
            entries: &[
                entry::uniform(0, compute),
                entry::storage(1, compute),
                entry::storage(2, compute),
                entry::storage(3, compute),
                entry::storage(4, compute),
                entry::storage(5, compute),
                entry::storage_read_write(6, compute),
                entry::storage_read_write(7, compute),
                entry::storage_read_write(8, compute),
            ],
        });
        let module = RELIGHT_SHADER.module(setup.device, false);
        let pipeline_layout = setup.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("wavelet-relight"),
            bind_group_layouts: &[Some(&relight_layout)],
            immediate_size: 0,
        });
        let relight = setup.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("wavelet-relight"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("relight"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self {
            pipeline: setup.surface_pipeline(SHADER, &layout),
            params: uniform_buffer::<WaveletParams>(setup.device, "wavelet-params"),
            layout,
            relight_layout,
            relight,
            relight_on: RelightOn::Auto,
            receivers: None,
            lit: None,
            bound: None,
            relit: None,
        }
    }

    /// Where the next relights run. What was built for the other side (the environment
    /// buffer, the CPU's frame tables, the last products) is dropped.
    pub(crate) fn set_relight_on(&mut self, on: RelightOn) {
        if on != self.relight_on {
            self.relight_on = on;
            self.lit = None;
            self.relit = None;
        }
    }

    /// Whether the kernel runs on the GPU for this device.
    fn kernel_on_gpu(&self, gpu: &GpuContext) -> bool {
        !self.relight_on.on_cpu(gpu)
    }

    fn upload_receivers(gpu: &GpuContext, data: &WaveletSurfaces) -> Result<Receivers, RenderError> {
        let kept = data.details.kept;
        let vertices = LitReceivers::upload(gpu, "vertices", &data.vertices, kept)?;
        let texels = data.texels.as_ref().map(|t| LitReceivers::upload(gpu, "texels", t, kept)).transpose()?;
        Ok(Receivers {
            key: data.receivers_key(),
            texel_size: texels.as_ref().map(|_| data.texel_size as u32),
            vertices,
            texels,
            cell_samples: storage_buffer(gpu, "wavelet-cell-samples", &data.cell_samples),
            cell_tables: Self::cell_tables(gpu, data),
            details_key: data.details_key(),
        })
    }

    fn cell_tables(gpu: &GpuContext, data: &WaveletSurfaces) -> wgpu::Buffer {
        let tables: Vec<f32> = data.diffuse_table.iter().chain(&data.details.squared).copied().collect();
        storage_buffer(gpu, "wavelet-cell-tables", &tables)
    }

    fn bind(&self, gpu: &GpuContext, receivers: &Receivers, data: &WaveletSurfaces) -> Result<Bound, RenderError> {
        let specular = storage_buffer(gpu, "wavelet-specular", &data.specular_tables);
        let layers = storage_buffer(gpu, "wavelet-vertex-layers", &data.vertex_layers);
        let ranges = storage_buffer(gpu, "wavelet-specular-ranges", &data.specular_ranges);
        let cells = storage_buffer(gpu, "wavelet-specular-cells", &data.specular_cells);
        let fine: Vec<half::f16> = data.fine_specular_tables.iter().flat_map(|t| t.iter().copied()).collect();
        let limit = gpu.device.limits().max_storage_buffer_binding_size.min(gpu.device.limits().max_buffer_size);
        if (fine.len() * 2) as u64 > limit {
            return Err(RenderError::Invalid(format!(
                "the glossy materials' fine lobe tables need {} MiB but this GPU binds at most {} MiB: use fewer \
                 glossy materials or set the wavelet detail terms to 0",
                (fine.len() * 2) >> 20,
                limit >> 20
            )));
        }
        let fine = storage_buffer(gpu, "wavelet-fine-specular", &fine);
        let no_irradiance = storage_buffer::<[f32; 4]>(gpu, "wavelet-no-texels", &[]);
        let no_products = storage_buffer::<u32>(gpu, "wavelet-no-texels", &[]);
        fn resource(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        let texels = receivers.texels.as_ref();
        let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("wavelet"),
            layout: &self.layout,
            entries: &[
                resource(0, &self.params),
                resource(1, &receivers.vertices.products),
                resource(2, &receivers.vertices.irradiance),
                resource(3, &specular),
                resource(4, texels.map_or(&no_irradiance, |t| &t.irradiance)),
                resource(5, texels.map_or(&no_products, |t| &t.products)),
                resource(6, &layers),
                resource(7, &ranges),
                resource(8, &cells),
                resource(9, &receivers.vertices.details),
                resource(10, texels.map_or(&no_products, |t| &t.details)),
                resource(11, &fine),
            ],
        });
        Ok(Bound { key: data.key, bind_group })
    }

    /// Uploads the prefiltered environment and binds it with each receiver set.
    fn light(&self, gpu: &GpuContext, receivers: &Receivers, data: &WaveletSurfaces) -> Result<Lit, RenderError> {
        // The kernel runs wherever the frame brings no relit receivers, so it always has the
        // environment (a few hundred KiB prefiltered).
        let environment = stage_value::<CubeMap>(&data.environment)?;
        let texels: Vec<[f32; 4]> = environment.texels.iter().map(|t| [t[0], t[1], t[2], 0.0]).collect();
        let buffer = storage_buffer(gpu, "wavelet-environment", &texels);
        let bind = |set: &LitReceivers| {
            let entries = [
                &set.params,
                &set.frames,
                &set.visibility,
                &buffer,
                &receivers.cell_samples,
                &receivers.cell_tables,
                &set.products,
                &set.irradiance,
                &set.details,
            ];
            let entries: Vec<wgpu::BindGroupEntry> = entries
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
                .collect();
            let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("wavelet-relight"),
                layout: &self.relight_layout,
                entries: &entries,
            });
            (set.count, group)
        };
        let bind_groups = std::iter::once(&receivers.vertices).chain(&receivers.texels).map(bind).collect();
        Ok(Lit { environment_key: data.environment.key, bind_groups })
    }

    /// Rebuilds every receiver's `P` and `E` with the compute kernel.
    fn relight_on_gpu(
        &self,
        gpu: &GpuContext,
        receivers: &Receivers,
        lit: &Lit,
        data: &WaveletSurfaces,
    ) -> Result<(), RenderError> {
        let size = stage_value::<CubeMap>(&data.environment)?.size;
        let max_columns = gpu.device.limits().max_compute_workgroups_per_dimension;
        let samples_per_cell = (data.cell_samples.len() / data.cells.max(1)) as u32;
        let sets = std::iter::once(&receivers.vertices).chain(&receivers.texels);
        let mut dispatches = Vec::new();
        for (set, (count, group)) in sets.zip(&lit.bind_groups) {
            let groups = count.div_ceil(WORKGROUP).max(1);
            let columns = groups.min(max_columns);
            let params = RelightParams {
                inverse_rotation: data.rotation.transpose().as_mat3(),
                receivers: *count,
                cells: data.cells as u32,
                samples_per_cell,
                face_size: size as u32,
                row_width: columns * WORKGROUP,
                details_kept: data.details.kept as u32,
            };
            write_uniform(&gpu.queue, &set.params, &params);
            dispatches.push((group, columns, groups.div_ceil(columns)));
        }
        let mut encoder =
            gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("wavelet-relight") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.relight);
            for (group, columns, rows) in dispatches {
                pass.set_bind_group(0, group, &[]);
                pass.dispatch_workgroups(columns, rows, 1);
            }
        }
        gpu.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Uploads every receiver's `P`, `E` and detail terms as the engine relit them.
    fn upload_relit(gpu: &GpuContext, receivers: &Receivers, relit: &RelitSets) -> Result<(), RenderError> {
        let sets = std::iter::once((&receivers.vertices, Some(&relit.vertices)))
            .chain(receivers.texels.iter().map(|t| (t, relit.texels.as_ref())));
        for (buffers, relit) in sets {
            let relit =
                stage_value::<RelitReceivers>(relit.ok_or_else(|| {
                    RenderError::Invalid("the frame's texels were not relit with its vertices".into())
                })?)?;
            // Each buffer is filled whole (no detail terms: none kept, and none read).
            let parts: [(&str, &[u8], &wgpu::Buffer); 3] = [
                ("products", bytemuck::cast_slice(&relit.products), &buffers.products),
                ("diffuse transfer", bytemuck::cast_slice(&relit.irradiance), &buffers.irradiance),
                ("detail terms", bytemuck::cast_slice(&relit.details), &buffers.details),
            ];
            for ((what, bytes, buffer), size) in parts.into_iter().zip(buffers.sizes) {
                if bytes.len() as u64 != size {
                    return Err(RenderError::Invalid(format!(
                        "the relit {what} are {} bytes for receivers that take {size}",
                        bytes.len()
                    )));
                }
                if !bytes.is_empty() {
                    gpu.queue.write_buffer(buffer, 0, bytes);
                }
            }
        }
        Ok(())
    }
}

impl Pass for WaveletPass {
    type Data = WaveletSurfaces;

    fn of(frame: &lightloom_nodes::frame::FrameInputs) -> Option<&Self::Data> {
        match &frame.surfaces {
            lightloom_nodes::frame::Surfaces::Wavelet(data) => Some(data),
            _ => None,
        }
    }

    fn set_relight_on(&mut self, on: RelightOn) {
        WaveletPass::set_relight_on(self, on);
    }

    fn prepare(&mut self, gpu: &GpuContext, data: &WaveletSurfaces) -> Result<(), RenderError> {
        if stage_value::<CubeMap>(&data.environment)?.size == 0 {
            return Err(RenderError::Invalid("the wavelet modes were given no environment".into()));
        }
        // A material edit rebinds the tables; only new receivers re-upload them and relight.
        if self.receivers.as_ref().is_none_or(|r| r.key != data.receivers_key()) {
            self.receivers = None;
            self.lit = None;
            self.bound = None;
            self.receivers = Some(Self::upload_receivers(gpu, data)?);
        }
        // A material edit moves the detail nodes' weights.
        if let Some(r) = self.receivers.as_mut().filter(|r| r.details_key != data.details_key()) {
            r.cell_tables = Self::cell_tables(gpu, data);
            r.details_key = data.details_key();
            self.lit = None;
        }
        let receivers = self.receivers.as_ref().expect("uploaded above");
        if self.lit.as_ref().is_none_or(|l| l.environment_key != data.environment.key) {
            self.lit = Some(self.light(gpu, receivers, data)?);
        }
        if self.bound.as_ref().is_none_or(|b| b.key != data.key) {
            self.bound = Some(self.bind(gpu, receivers, data)?);
        }
        let state = (receivers.key, data.environment.key, data.inverse_rotation(), receivers.details_key);
        if self.relit != Some(state) {
            self.relit = None;
            let lit = self.lit.as_ref().expect("lit above");
            // On the CPU the engine relights (the frame's `relit`); without that, the kernel.
            match data.relit.as_ref().filter(|_| !self.kernel_on_gpu(gpu)) {
                Some(relit) => Self::upload_relit(gpu, receivers, relit)?,
                None => self.relight_on_gpu(gpu, receivers, lit, data)?,
            }
            self.relit = Some(state);
        }
        let cells = data.cells as u32;
        let albedo: [glam::Vec3; MAX_MATERIALS] = vec3s(&data.albedo);
        let materials = std::array::from_fn(|m| {
            let specular = data.specular.get(m).copied().flatten();
            WaveletMaterial {
                albedo: albedo[m],
                glossy: u32::from(specular.is_some()),
                specular: specular.map_or(glam::Vec3::ZERO, |s| glam::DVec3::from(s).as_vec3()),
                fine_offset: data.fine_specular_offsets.get(m).copied().unwrap_or(0),
            }
        });
        let params = WaveletParams {
            cells,
            specular_stride: WaveletSurfaces::specular_stride(data.cells) as u32,
            theta_steps: THETA_STEPS as u32,
            phi_steps: PHI_STEPS as u32,
            texels_bound: u32::from(receivers.texel_size.is_some()),
            texel_size: receivers.texel_size.unwrap_or(0),
            details_kept: data.details.kept as u32,
            materials,
        };
        write_uniform(&gpu.queue, &self.params, &params);
        Ok(())
    }
}

impl Draw for WaveletPass {
    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, geometry: Option<&GeometryBuffers>, normal_maps: bool) {
        let (Some(geometry), Some(bound)) = (geometry, &self.bound) else { return };
        pass.set_pipeline(self.pipeline.get(normal_maps));
        pass.set_bind_group(2, &bound.bind_group, &[]);
        geometry.draw(pass);
    }
}

#[cfg(test)]
mod tests;
