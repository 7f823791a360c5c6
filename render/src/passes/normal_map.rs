//! The materials' normal maps (`normal_map.wgsl`): group 4 of every scene pass, read in the
//! same fragment as every surface. Uploads each mapped material's NDF moment pyramid as two
//! mip-mapped half-float texture-array layers, which the GPU then filters trilinearly and
//! anisotropically (the moments are linear in the texels), and its vMF lobes as one texture;
//! draws nothing itself.

use super::{entry, stage_value, uniform_buffer, write_uniform};
use crate::{GpuContext, RenderError};
use glam::{DVec3, Vec3, Vec4};
use lightloom_nodes::cubemap::CubeMap;
use lightloom_nodes::frame::{HIGHLIGHT_BANDS, MAX_MATERIALS, NormalMapFrame};
use lightloom_nodes::kinds::brdf_normal_map::NormalFilter;
use lightloom_nodes::normal_filtering::{MomentPyramid, VmfPyramid};
use lightloom_nodes::reflected_lobe;
use lightloom_nodes::specular_cube::SpecularCube;

/// vMF levels per material, from the map's own (`normal_map.wgsl` `NDF_LEVELS`; a 2048² map has 12).
const LEVELS: usize = 12;
/// Lobes per row of the lobe texture (`NDF_LOBE_ROW`).
const LOBE_ROW: usize = 4096;

/// Per material, its moment pyramid's stage key and its vMF lobes' (none without a map).
type PyramidKeys = Option<(u128, Option<u128>)>;

/// `normal_map.wgsl` `NormalMapMaterial`.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct NormalMapMaterial {
    /// 0 no map, 1 SH NDF, 2 vMF mixture, 3 Toksvig, 4 averaged normals.
    pub(crate) filter_kind: u32,
    /// Repeats per unit of UV.
    pub(crate) tiling: f32,
    pub(crate) fitted_levels: u32,
    pub(crate) layer: u32,
}

/// `normal_map.wgsl` `VmfLevel`.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct VmfLevel {
    pub(crate) first: u32,
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// Map texels per texel side.
    pub(crate) texel_span: u32,
    /// Lobes per texel.
    pub(crate) count: u32,
    /// A uniform array's elements are 16-byte aligned.
    pub(crate) pad_a: u32,
    pub(crate) pad_b: u32,
    pub(crate) pad_c: u32,
}

/// `normal_map.wgsl` `HighlightLobe`.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct HighlightLobe {
    pub(crate) weight: Vec3,
    /// 0 without a glossy lobe, else 1 + its `reflected_lobe::LobeShape`.
    pub(crate) glossy: u32,
    /// The GGX α of its equivalent Phong exponent.
    pub(crate) alpha: f32,
}

/// `normal_map.wgsl` `NormalMaps`.
#[derive(encase::ShaderType)]
pub(crate) struct NormalParams {
    pub(crate) materials: [NormalMapMaterial; MAX_MATERIALS],
    pub(crate) scale_vertex_diffuse: u32,
    pub(crate) vertex_highlights: u32,
    pub(crate) irradiance: [Vec3; 9],
    pub(crate) vmf_levels: [VmfLevel; MAX_MATERIALS * LEVELS],
    pub(crate) highlight_radiance: [Vec3; HIGHLIGHT_BANDS * HIGHLIGHT_BANDS],
    /// Four factors per vector, material `m` at `[2m, 2m + 1]`.
    pub(crate) highlight_factors: [Vec4; 2 * MAX_MATERIALS],
    pub(crate) highlight_lobes: [HighlightLobe; MAX_MATERIALS],
    /// Roughness levels of the bound prefiltered light (0: none, H from the SH).
    pub(crate) highlight_cube_levels: u32,
    /// The reflected lobe per shape, view cosine and α (nodes `reflected_lobe::table`): E, t
    /// and b a vector.
    pub(crate) reflected_lobe: [Vec4; REFLECTED_LOBE_VECTORS],
}

/// The size of `normal_map.wgsl`'s `NormalMaps.reflected_lobe`: an entry a vector.
const REFLECTED_LOBE_VECTORS: usize =
    reflected_lobe::LobeShape::ALL.len() * reflected_lobe::MU_STEPS * reflected_lobe::ALPHA_STEPS;

impl Default for NormalParams {
    fn default() -> Self {
        Self {
            materials: [NormalMapMaterial::default(); MAX_MATERIALS],
            scale_vertex_diffuse: 0,
            vertex_highlights: 0,
            irradiance: [Vec3::ZERO; 9],
            vmf_levels: [VmfLevel::default(); MAX_MATERIALS * LEVELS],
            highlight_radiance: [Vec3::ZERO; HIGHLIGHT_BANDS * HIGHLIGHT_BANDS],
            highlight_factors: [Vec4::ZERO; 2 * MAX_MATERIALS],
            highlight_lobes: [HighlightLobe::default(); MAX_MATERIALS],
            highlight_cube_levels: 0,
            reflected_lobe: reflected_lobe_vectors(),
        }
    }
}

/// The reflected-lobe table, an entry a vector.
fn reflected_lobe_vectors() -> [Vec4; REFLECTED_LOBE_VECTORS] {
    let entries = &reflected_lobe::table().entries;
    std::array::from_fn(|k| Vec3::from_array(entries[k]).extend(0.0))
}

pub(crate) struct NormalMapPass {
    pub layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    /// The maps' anisotropic sampler (binding 3) and the prefiltered light's trilinear one
    /// (binding 6: an explicit level of detail through an anisotropic sampler is not honoured
    /// everywhere; lavapipe takes it from the derivatives).
    samplers: [wgpu::Sampler; 2],
    pub bind_group: wgpu::BindGroup,
    /// The pyramids' stage keys the bound textures hold.
    uploaded: Option<Vec<PyramidKeys>>,
    /// Per material: its layer and fitted vMF levels (first lobe, width, height, texel span,
    /// lobes a texel), as uploaded.
    slots: Vec<Option<(u32, Vec<[u32; 5]>)>>,
    /// Bindings 1, 2 and 4.
    views: [wgpu::TextureView; 3],
    /// The prefiltered light's view (binding 5), its stage key and levels.
    cube: wgpu::TextureView,
    cube_uploaded: Option<(u128, u32)>,
}

impl NormalMapPass {
    pub fn new(gpu: &GpuContext) -> Self {
        let layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("normal maps"),
            entries: &[
                entry::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                entry::texture(1, wgpu::TextureViewDimension::D2Array, true),
                entry::texture(2, wgpu::TextureViewDimension::D2Array, true),
                entry::sampler(3),
                entry::texture(4, wgpu::TextureViewDimension::D2, false),
                entry::texture(5, wgpu::TextureViewDimension::Cube, true),
                entry::sampler(6),
            ],
        });
        let params = uniform_buffer::<NormalParams>(&gpu.device, "normal maps");
        let samplers = [
            gpu.device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("normal maps"),
                address_mode_u: wgpu::AddressMode::Repeat,
                address_mode_v: wgpu::AddressMode::Repeat,
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: wgpu::MipmapFilterMode::Linear,
                anisotropy_clamp: 16,
                ..Default::default()
            }),
            gpu.device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("normal-map highlight light"),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: wgpu::MipmapFilterMode::Linear,
                ..Default::default()
            }),
        ];
        let cube = upload_cube(gpu, &SpecularCube { levels: vec![CubeMap::new(1, vec![[0.0; 3]; 6])] });
        let views = Self::upload(gpu, &[], (1, 1), &[[0.0; 4]]);
        let bind_group = bind(gpu, &layout, &params, &samplers, &views, &cube);
        Self {
            layout,
            params,
            samplers,
            bind_group,
            views,
            uploaded: None,
            slots: Vec::new(),
            cube,
            cube_uploaded: None,
        }
    }

    /// The moment pyramids' two texture arrays and the lobe texture.
    fn upload(
        gpu: &GpuContext,
        pyramids: &[&MomentPyramid],
        (width, height): (usize, usize),
        lobes: &[[f32; 4]],
    ) -> [wgpu::TextureView; 3] {
        let levels = pyramids.first().map_or(1, |p| p.levels.len()) as u32;
        let layers = pyramids.len().max(1) as u32;
        let moments = |label: &str, half: usize| {
            let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width: width as u32, height: height as u32, depth_or_array_layers: layers },
                mip_level_count: levels,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba16Float,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            for (layer, pyramid) in pyramids.iter().enumerate() {
                for (mip, level) in pyramid.levels.iter().enumerate() {
                    let texels: Vec<half::f16> = level
                        .texels
                        .iter()
                        .flat_map(|t| t[4 * half..4 * half + 4].iter().map(|v| half::f16::from_f32(*v)))
                        .collect();
                    gpu.queue.write_texture(
                        wgpu::TexelCopyTextureInfo {
                            texture: &texture,
                            mip_level: mip as u32,
                            origin: wgpu::Origin3d { x: 0, y: 0, z: layer as u32 },
                            aspect: wgpu::TextureAspect::All,
                        },
                        bytemuck::cast_slice(&texels),
                        wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(level.width as u32 * 8),
                            rows_per_image: Some(level.height as u32),
                        },
                        wgpu::Extent3d {
                            width: level.width as u32,
                            height: level.height as u32,
                            depth_or_array_layers: 1,
                        },
                    );
                }
            }
            texture.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            })
        };
        let (a, b) = (moments("normal moments (mean, xx)", 0), moments("normal moments (yy, xy, xz, yz)", 1));
        let rows = lobes.len().div_ceil(LOBE_ROW).max(1);
        let columns = lobes.len().clamp(1, LOBE_ROW);
        let mut padded = lobes.to_vec();
        padded.resize(rows * columns, [0.0; 4]);
        let lobe_texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("normal-map vMF lobes"),
            size: wgpu::Extent3d { width: columns as u32, height: rows as u32, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        gpu.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &lobe_texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(&padded),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(columns as u32 * 16),
                rows_per_image: Some(rows as u32),
            },
            wgpu::Extent3d { width: columns as u32, height: rows as u32, depth_or_array_layers: 1 },
        );
        [a, b, lobe_texture.create_view(&Default::default())]
    }

    /// Uniforms every frame; textures when a pyramid's stage changes.
    pub fn prepare(&mut self, gpu: &GpuContext, frame: &NormalMapFrame) -> Result<(), RenderError> {
        let keys: Vec<PyramidKeys> = frame
            .materials
            .iter()
            .take(MAX_MATERIALS)
            .map(|m| m.as_ref().map(|d| (d.moments.key, d.lobes.as_ref().map(|l| l.key))))
            .collect();
        if self.uploaded.as_ref() != Some(&keys) {
            let mut pyramids = Vec::new();
            let mut lobes: Vec<[f32; 4]> = Vec::new();
            self.slots.clear();
            let mut size = (1, 1);
            for detail in frame.materials.iter().take(MAX_MATERIALS) {
                let Some(detail) = detail else {
                    self.slots.push(None);
                    continue;
                };
                let pyramid = stage_value::<MomentPyramid>(&detail.moments)?;
                let Some(finest) = pyramid.levels.first() else {
                    self.slots.push(None);
                    continue;
                };
                size = (finest.width, finest.height);
                let mut levels = Vec::new();
                if let Some(keyed) = &detail.lobes {
                    let fitted = stage_value::<VmfPyramid>(keyed)?;
                    for level in fitted.levels.iter().take(LEVELS) {
                        let block = finest.width.div_ceil(level.width).max(1);
                        levels.push([
                            lobes.len() as u32,
                            level.width as u32,
                            level.height as u32,
                            block as u32,
                            level.lobes_per_texel as u32,
                        ]);
                        lobes.extend_from_slice(&level.lobes);
                    }
                }
                self.slots.push(Some((pyramids.len() as u32, levels)));
                pyramids.push(pyramid);
            }
            let max = gpu.device.limits().max_texture_dimension_2d as usize;
            if size.0 > max || size.1 > max || lobes.len().div_ceil(LOBE_ROW) > max {
                return Err(RenderError::Invalid(format!(
                    "a {}×{} normal map is larger than this GPU's textures ({max} a side)",
                    size.0, size.1
                )));
            }
            self.views = Self::upload(gpu, &pyramids, size, &lobes);
            self.uploaded = Some(keys);
            self.bind_group = bind(gpu, &self.layout, &self.params, &self.samplers, &self.views, &self.cube);
        }
        let cube = frame.vertex_highlight.as_ref().and_then(|h| h.cube.as_ref());
        if let Some(keyed) = cube
            && self.cube_uploaded.map(|(key, _)| key) != Some(keyed.key)
        {
            let prefiltered = stage_value::<SpecularCube>(keyed)?;
            self.cube = upload_cube(gpu, prefiltered);
            self.cube_uploaded = Some((keyed.key, prefiltered.levels.len() as u32));
            self.bind_group = bind(gpu, &self.layout, &self.params, &self.samplers, &self.views, &self.cube);
        }
        let v3 = |v: &[f64; 3]| DVec3::from(*v).as_vec3();
        let mut params = NormalParams::default();
        for (m, (slot, detail)) in self.slots.iter().zip(&frame.materials).enumerate() {
            let (Some((layer, levels)), Some(detail)) = (slot, detail) else { continue };
            let filter_kind = match detail.settings.filter {
                NormalFilter::Sh => 1,
                NormalFilter::Vmf => 2,
                NormalFilter::Toksvig => 3,
                NormalFilter::None => 4,
            };
            let fitted_levels = if detail.lobes.is_some() { levels.len() as u32 } else { 0 };
            let tiling = detail.settings.tiling as f32;
            params.materials[m] = NormalMapMaterial { filter_kind, tiling, fitted_levels, layer: *layer };
            for (k, &[first, width, height, texel_span, count]) in levels.iter().enumerate() {
                params.vmf_levels[m * LEVELS + k] =
                    VmfLevel { first, width, height, texel_span, count, ..Default::default() };
            }
        }
        if let Some(e) = &frame.vertex_diffuse_scale {
            params.scale_vertex_diffuse = 1;
            for (dst, src) in params.irradiance.iter_mut().zip(&e.coeffs) {
                *dst = v3(src);
            }
        }
        if let Some(highlight) = &frame.vertex_highlight {
            params.vertex_highlights = 1;
            if let (Some(keyed), Some((key, levels))) = (&highlight.cube, self.cube_uploaded)
                && keyed.key == key
            {
                params.highlight_cube_levels = levels;
            }
            for (dst, src) in params.highlight_radiance.iter_mut().zip(&highlight.radiance.coeffs) {
                *dst = v3(src);
            }
            for (m, lobe) in highlight.lobes.iter().enumerate().take(MAX_MATERIALS) {
                let Some(lobe) = lobe else { continue };
                // The lobe about the mirror direction of exponent s is Blinn-Phong's 4s
                // (`Brdf::equivalent_phong_exponent`), GGX's α = sqrt(2 / (4s + 2)) (Walter et al.
                // 2007).
                let alpha = (2.0 / (4.0 * lobe.exponent + 2.0)).sqrt() as f32;
                let glossy = 1 + highlight.shapes.get(m).map_or(0, |s| *s as u32);
                params.highlight_lobes[m] = HighlightLobe { weight: v3(&lobe.weight), glossy, alpha };
                for (l, f) in lobe.factors.iter().enumerate().take(HIGHLIGHT_BANDS) {
                    params.highlight_factors[2 * m + l / 4][l % 4] = *f as f32;
                }
            }
        }
        write_uniform(&gpu.queue, &self.params, &params);
        Ok(())
    }
}

/// Group 4 from the uploaded views.
fn bind(
    gpu: &GpuContext,
    layout: &wgpu::BindGroupLayout,
    params: &wgpu::Buffer,
    [sampler, cube_sampler]: &[wgpu::Sampler; 2],
    [a, b, lobes]: &[wgpu::TextureView; 3],
    cube: &wgpu::TextureView,
) -> wgpu::BindGroup {
    let view = wgpu::BindingResource::TextureView;
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("normal maps"),
        layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: view(a) },
            wgpu::BindGroupEntry { binding: 2, resource: view(b) },
            wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::Sampler(sampler) },
            wgpu::BindGroupEntry { binding: 4, resource: view(lobes) },
            wgpu::BindGroupEntry { binding: 5, resource: view(cube) },
            wgpu::BindGroupEntry { binding: 6, resource: wgpu::BindingResource::Sampler(cube_sampler) },
        ],
    })
}

/// A prefiltered cube's levels as one mip-mapped half-float cube texture (level `m` its mip `m`).
fn upload_cube(gpu: &GpuContext, cube: &SpecularCube) -> wgpu::TextureView {
    let size = cube.levels[0].size;
    // Layer-major: each face's mips in turn.
    let mut texels = Vec::new();
    for face in 0..6 {
        for level in &cube.levels {
            let n = level.size * level.size;
            texels.extend_from_slice(&level.texels[face * n..(face + 1) * n]);
        }
    }
    let mips = (size as u32, cube.levels.len() as u32);
    super::upload_layered(gpu, "normal-map highlight light", mips, 6, &texels, wgpu::TextureViewDimension::Cube)
}
