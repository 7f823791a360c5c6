//! Blocker-sphere shadows on the GPU (Sun 2008 §5.2), split as the thesis splits them: the
//! CPU clusters the receivers and lists the spheres within each cluster's reach
//! ([`cull`]); the GPU sums each receiver's log visibilities (Eq. 5.13) and exponentiates once
//! (PS*-p, Eqs. 5.24–5.27, or HYB), one invocation per receiver, then multiplies each of the
//! receiver's transport vectors by the result (Eq. 5.8), one invocation per vector
//! (`shaders/shexp.wgsl`). The CPU twin, which
//! the engine's `blocked_transport` stage runs, is `lightloom_nodes::sh_exponential`.

use crate::{GpuContext, RenderError};
use glam::DVec3;
use lightloom_nodes::kinds::blockers::BlockerSet;
use lightloom_nodes::sh::GauntTable;
use lightloom_nodes::sh_exponential::{Blocker, ExpMethod, MIN_ANGULAR_RADIUS, receiver_parts, spheres_in_reach};
use std::time::{Duration, Instant};
use wgpu::util::DeviceExt;

pub(crate) const SHADER: crate::shaders::Shader =
    crate::shaders::Shader::file("shexp", crate::shaders::source!("shexp.wgsl"));

/// Visibility bands the kernel holds per receiver (`MAX_B` in the shader).
pub const MAX_BLOCKER_BANDS: usize = 6;
/// Transport bands it multiplies (`MAX_T`).
pub const MAX_TRANSPORT_BANDS: usize = 14;
const WORKGROUP: u32 = 64;
/// Words per receiver between the kernels: a reached flag and the visibility (`shexp.wgsl`).
const VISIBILITY_STRIDE: usize = 1 + MAX_BLOCKER_BANDS * MAX_BLOCKER_BANDS;

/// `shexp.wgsl` `ShexpParams`.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct ShexpParams {
    pub(crate) receivers: u32,
    pub(crate) bands_b: u32,
    pub(crate) bands_t: u32,
    pub(crate) vectors_per_receiver: u32,
    pub(crate) series_degree: u32,
    pub(crate) table_entries: u32,
    pub(crate) ol_bins: u32,
    pub(crate) gaunt_bb_count: u32,
    pub(crate) gaunt_tb_count: u32,
    pub(crate) offset_blockers: u32,
    pub(crate) offset_parts: u32,
    pub(crate) offset_log: u32,
    pub(crate) offset_ol: u32,
    pub(crate) offset_gaunt_bb: u32,
    pub(crate) offset_gaunt_tb: u32,
    pub(crate) row_stride: u32,
    pub(crate) strength: f32,
    pub(crate) ol_max_norm: f32,
    pub(crate) ol_halving: f32,
    pub(crate) min_sin: f32,
}

/// The CPU's share of an update: each receiver's cluster and each cluster's spheres.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Culled {
    /// Per receiver, its cluster.
    pub part_of: Vec<u32>,
    /// Per cluster, the range of `spheres` listing the spheres within its reach.
    pub ranges: Vec<(u32, u32)>,
    pub spheres: Vec<u32>,
}

/// Clusters `positions` (at most `part_size` each, `sh_exponential::receiver_parts`) and lists
/// the spheres that may reach each cluster (`spheres_in_reach`).
pub fn cull(positions: &[DVec3], blockers: &[Blocker], part_size: usize) -> Culled {
    let mut culled = Culled { part_of: vec![0; positions.len()], ..Default::default() };
    for (p, indices) in receiver_parts(positions, part_size).iter().enumerate() {
        let points: Vec<DVec3> = indices.iter().map(|&i| positions[i]).collect();
        let near = spheres_in_reach(&points, blockers);
        culled.ranges.push((culled.spheres.len() as u32, near.len() as u32));
        culled.spheres.extend(near.iter().map(|&s| s as u32));
        for &i in indices {
            culled.part_of[i] = p as u32;
        }
    }
    culled
}

/// Where the GPU's share of one update went.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuTimings {
    /// Packing and uploading receivers, spheres, lists and vectors.
    pub upload: Duration,
    /// The kernel, submit to finish.
    pub kernel: Duration,
    /// Copying the vectors back and mapping them.
    pub readback: Duration,
}

/// The two compute pipelines and the set's constant tables (log caps, OL, the two Gaunt
/// tables).
pub struct GpuBlockedProduct {
    visibility: wgpu::ComputePipeline,
    multiply: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: ShexpParams,
    /// Log table, OL's a and b, Gaunt b×b→b, Gaunt t×b→t, as words; offsets relative to it.
    tables: Vec<u32>,
}

impl GpuBlockedProduct {
    /// For `set`'s spheres' order and exponential, multiplying transport of `bands_t` bands.
    pub fn new(gpu: &GpuContext, set: &BlockerSet, bands_t: usize) -> Result<Self, RenderError> {
        let bands_b = set.bands();
        if bands_b == 0 || bands_b > MAX_BLOCKER_BANDS || bands_t == 0 || bands_t > MAX_TRANSPORT_BANDS {
            return Err(RenderError::Invalid(format!(
                "the GPU blocker product takes up to {MAX_BLOCKER_BANDS} visibility bands and {MAX_TRANSPORT_BANDS} \
                 transport bands, not {bands_b} and {bands_t}"
            )));
        }
        let mut tables: Vec<u32> = Vec::new();
        let mut params = ShexpParams {
            bands_b: bands_b as u32,
            bands_t: bands_t as u32,
            series_degree: match set.method {
                ExpMethod::PsStar(p) => p.max(1) as u32,
                ExpMethod::Hyb => 0,
            },
            table_entries: set.tables.log.entries as u32,
            ol_bins: set.tables.ol.a.len() as u32,
            strength: set.strength as f32,
            ol_max_norm: set.tables.ol.max_norm as f32,
            ol_halving: set.tables.ol.halving_threshold as f32,
            min_sin: MIN_ANGULAR_RADIUS.sin() as f32,
            ..Default::default()
        };
        let floats = |values: &mut dyn Iterator<Item = f64>, out: &mut Vec<u32>| {
            out.extend(values.map(|v| (v as f32).to_bits()));
        };
        params.offset_log = 0;
        floats(&mut set.tables.log.zonal.iter().copied(), &mut tables);
        params.offset_ol = tables.len() as u32;
        floats(&mut set.tables.ol.a.iter().chain(&set.tables.ol.b).copied(), &mut tables);
        let pack = |gaunt: &GauntTable, out: &mut Vec<u32>| {
            for &(i, j, k, c) in gaunt.entries() {
                out.extend([i | (j << 10) | (k << 20), (c as f32).to_bits()]);
            }
        };
        let bb = GauntTable::new(bands_b, bands_b, bands_b);
        params.offset_gaunt_bb = tables.len() as u32;
        params.gaunt_bb_count = bb.len() as u32;
        pack(&bb, &mut tables);
        let tb = GauntTable::new(bands_t, bands_b, bands_t);
        params.offset_gaunt_tb = tables.len() as u32;
        params.gaunt_tb_count = tb.len() as u32;
        pack(&tb, &mut tables);

        let device = &gpu.device;
        let module = SHADER.module(device, false);
        use crate::passes::entry;
        let compute = wgpu::ShaderStages::COMPUTE;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shexp"),
            entries: &[
                entry::uniform(0, compute),
                entry::storage(1, compute),
                entry::storage(2, compute),
                entry::storage_read_write(3, compute),
                entry::storage_read_write(4, compute),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("shexp"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        Ok(Self {
            visibility: pipeline("visibility_main"),
            multiply: pipeline("multiply_main"),
            layout,
            params,
            tables,
        })
    }

    /// Multiplies `vectors` (each `bands_t²` per receiver, receiver-major, like
    /// `ShTransport::visibility` and `::transfer`) by the visibility of `blockers` at each of
    /// `positions`, as `BlockedProduct::apply` does on the CPU. `culled` comes from [`cull`]
    /// on the same positions and blockers.
    pub fn apply(
        &self,
        gpu: &GpuContext,
        positions: &[DVec3],
        blockers: &[Blocker],
        culled: &Culled,
        vectors: &mut [&mut [f32]],
    ) -> Result<GpuTimings, RenderError> {
        let mut timings = GpuTimings::default();
        let n_t = (self.params.bands_t * self.params.bands_t) as usize;
        if vectors.iter().any(|v| v.len() != positions.len() * n_t) || culled.part_of.len() != positions.len() {
            return Err(RenderError::Invalid(format!(
                "the blocker product needs {n_t} coefficients per vector and one cluster per receiver for {} receivers",
                positions.len()
            )));
        }
        if positions.is_empty() || vectors.is_empty() || self.params.strength <= 0.0 {
            return Ok(timings);
        }
        let start = Instant::now();
        // Words: spheres, cluster ranges (absolute), sphere lists, then the constant tables.
        let mut words: Vec<u32> = Vec::with_capacity(blockers.len() * 4 + culled.spheres.len() + self.tables.len());
        let mut params = self.params;
        params.receivers = positions.len() as u32;
        params.vectors_per_receiver = vectors.len() as u32;
        params.offset_blockers = 0;
        for b in blockers {
            words.extend(b.centre.iter().chain([&b.radius]).map(|&v| (v as f32).to_bits()));
        }
        params.offset_parts = words.len() as u32;
        let lists = params.offset_parts + 2 * culled.ranges.len() as u32;
        for &(first, count) in &culled.ranges {
            words.extend([lists + first, count]);
        }
        words.extend(&culled.spheres);
        let tables = words.len() as u32;
        words.extend(&self.tables);
        for offset in
            [&mut params.offset_log, &mut params.offset_ol, &mut params.offset_gaunt_bb, &mut params.offset_gaunt_tb]
        {
            *offset += tables;
        }
        let receivers: Vec<[f32; 4]> = positions
            .iter()
            .zip(&culled.part_of)
            .map(|(p, &part)| [p.x as f32, p.y as f32, p.z as f32, f32::from_bits(part)])
            .collect();
        let packed: Vec<f32> = vectors.iter().flat_map(|v| v.iter().copied()).collect();
        let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
        let bytes = packed.len() * 4;
        let visibility_bytes = positions.len() * VISIBILITY_STRIDE * 4;
        let buffer_limit = gpu.device.limits().max_buffer_size as usize;
        if [bytes, words.len() * 4, visibility_bytes].iter().any(|b| *b > limit.min(buffer_limit)) {
            return Err(RenderError::Invalid(format!(
                "the blocker product's {} MiB of transport exceed this GPU's storage binding of {} MiB; lower the \
                 scene's SH order or its vertex count",
                bytes >> 20,
                limit >> 20
            )));
        }
        // Invocations: one per receiver, then one per receiver and vector.
        let groups = |invocations: usize| invocations.div_ceil(WORKGROUP as usize) as u32;
        let columns = groups(packed.len() / n_t).min(gpu.device.limits().max_compute_workgroups_per_dimension);
        params.row_stride = columns * WORKGROUP;

        let device = &gpu.device;
        let init = |label: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        use wgpu::BufferUsages as U;
        let uniform = init("shexp params", &crate::passes::uniform_bytes(&params), U::UNIFORM);
        let receiver_buffer = init("shexp receivers", bytemuck::cast_slice(&receivers), U::STORAGE);
        let word_buffer = init("shexp words", bytemuck::cast_slice(&words), U::STORAGE);
        let vector_buffer = init("shexp vectors", bytemuck::cast_slice(&packed), U::STORAGE | U::COPY_SRC);
        let visibility = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shexp visibility"),
            size: (positions.len() * VISIBILITY_STRIDE * 4) as u64,
            usage: U::STORAGE,
            mapped_at_creation: false,
        });
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shexp readback"),
            size: bytes as u64,
            usage: U::COPY_DST | U::MAP_READ,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shexp"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: receiver_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: word_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: visibility.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: vector_buffer.as_entire_binding() },
            ],
        });
        gpu.wait()?;
        timings.upload = start.elapsed();

        let start = Instant::now();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("shexp") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_bind_group(0, &bind, &[]);
            for (pipeline, invocations) in [(&self.visibility, positions.len()), (&self.multiply, packed.len() / n_t)] {
                let groups = groups(invocations);
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(groups.min(columns), groups.div_ceil(columns), 1);
            }
        }
        gpu.queue.submit([encoder.finish()]);
        gpu.wait()?;
        timings.kernel = start.elapsed();

        let start = Instant::now();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("shexp copy") });
        encoder.copy_buffer_to_buffer(&vector_buffer, 0, &readback, 0, bytes as u64);
        gpu.queue.submit([encoder.finish()]);
        crate::capture::read_mapped(device, &readback, |mapped| {
            let values: &[f32] = bytemuck::cast_slice(mapped);
            for (v, chunk) in vectors.iter_mut().zip(values.chunks(positions.len() * n_t)) {
                v.copy_from_slice(chunk);
            }
        })?;
        timings.readback = start.elapsed();
        Ok(timings)
    }
}

#[cfg(test)]
mod tests;
