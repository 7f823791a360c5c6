//! Painted area lights in a frame (Sun 2008 §4.5).

use super::*;
use crate::kinds::area_light::AreaLight;

/// Painted area lights (Sun 2008 §4.5): diffuse light per vertex, drawn over the mode's
/// surfaces as `albedo · colour / π · E`, plus their glossy highlights toward the view (§4.9).
#[derive(Clone, Debug)]
pub struct AreaLightFrame {
    /// [`crate::kinds::output::area::AreaIrradiance`]: `E` per vertex from every linked light.
    pub irradiance: Keyed,
    /// [`crate::kinds::output::area::AreaHighlights`]: reflected radiance per vertex (none, or
    /// empty, without a glossy material).
    pub highlights: Option<Keyed>,
    /// Per material: diffuse albedo.
    pub albedo: Vec<[f64; 3]>,
    /// The lights as the reference samples them.
    pub emitters: Vec<crate::reference::AreaEmitter>,
    /// `E` per texel of the meshes with a visibility texture, drawn per pixel there instead of
    /// the vertices' (once traced).
    pub texels: Option<AreaTexels>,
}

/// Area-light irradiance per texel: one `size²` layer per mesh with a visibility texture
/// (layer-major, rows at increasing `v`), read bilinearly per pixel.
#[derive(Clone, Debug)]
pub struct AreaTexels {
    /// Changes whenever the values below do.
    pub key: Key,
    pub size: usize,
    /// RGB irradiance per texel slot (w unused); slots no triangle covers take their covered
    /// neighbours' mean, so filtering at a UV edge does not darken.
    pub irradiance: Arc<Vec<[f32; 4]>>,
    /// Per vertex: its mesh's layer, or -1 (lit per vertex).
    pub vertex_layers: Arc<Vec<i32>>,
}

/// Rings of uncovered texels around a chart that take their covered neighbours' mean.
const DILATION_RINGS: usize = 4;

impl AreaTexels {
    /// The texel irradiance (an [`crate::kinds::output::area::AreaIrradiance`] over `texels`'
    /// receivers) laid out per mesh layer; `None` without any texel.
    pub fn new(irradiance: &Keyed, texels: &Keyed, geometry: &Geometry) -> Result<Option<Self>, String> {
        let e = irradiance.value.expect::<crate::kinds::output::area::AreaIrradiance>().map_err(|e| e.to_string())?;
        let t = texels.value.expect::<crate::transport::TexelReceivers>().map_err(|e| e.to_string())?;
        if t.texels.is_empty() {
            return Ok(None);
        }
        if e.irradiance.len() != t.texels.len() {
            return Err(format!("the area lights cover {} of {} texels", e.irradiance.len(), t.texels.len()));
        }
        let meshes = geometry.meshes.value.expect::<crate::mesh::MeshSet>().map_err(|e| e.to_string())?;
        let mut mesh_layers = vec![-1i32; meshes.meshes.len()];
        let mut layers = 0;
        for &(mesh, ..) in &t.texels {
            let layer = mesh_layers.get_mut(mesh as usize).ok_or("a texel belongs to a mesh the scene lacks")?;
            if *layer < 0 {
                (*layer, layers) = (layers, layers + 1);
            }
        }
        let size = t.size;
        let mut values = vec![[0.0f32; 4]; layers as usize * size * size];
        let mut covered = vec![false; values.len()];
        for (&(mesh, x, y), c) in t.texels.iter().zip(&e.irradiance) {
            let at = (mesh_layers[mesh as usize] as usize * size + y as usize) * size + x as usize;
            values[at] = [c[0], c[1], c[2], 0.0];
            covered[at] = true;
        }
        dilate(&mut values, &mut covered, size);
        let vertex_layers =
            meshes.meshes.iter().zip(&mesh_layers).flat_map(|(m, &l)| std::iter::repeat_n(l, m.positions.len()));
        Ok(Some(Self {
            key: irradiance.key ^ texels.key.rotate_left(13) ^ geometry.meshes.key.rotate_left(29),
            size,
            irradiance: Arc::new(values),
            vertex_layers: Arc::new(vertex_layers.collect()),
        }))
    }
}

/// Gives each uncovered slot next to covered ones their mean, [`DILATION_RINGS`] times.
fn dilate(values: &mut [[f32; 4]], covered: &mut [bool], size: usize) {
    for _ in 0..DILATION_RINGS {
        let mut added = Vec::new();
        for (at, _) in covered.iter().enumerate().filter(|(_, c)| !**c) {
            let (layer, x, y) = (at / (size * size), at % size, at / size % size);
            let (mut sum, mut n) = ([0.0f32; 4], 0.0);
            for (dx, dy) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if (0..size as i64).contains(&nx) && (0..size as i64).contains(&ny) {
                    let near = (layer * size + ny as usize) * size + nx as usize;
                    if covered[near] {
                        (0..4).for_each(|c| sum[c] += values[near][c]);
                        n += 1.0;
                    }
                }
            }
            if n > 0.0 {
                added.push((at, sum.map(|v| v / n)));
            }
        }
        if added.is_empty() {
            break;
        }
        for (at, value) in added {
            values[at] = value;
            covered[at] = true;
        }
    }
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
        let e = irradiance.value.expect::<crate::kinds::output::area::AreaIrradiance>().map_err(|e| e.to_string())?;
        if e.irradiance.len() != vertices {
            return Err(format!("the area lights cover {} receivers for {vertices} vertices", e.irradiance.len()));
        }
        if let Some(h) = &highlights {
            let h = h.value.expect::<crate::kinds::output::area::AreaHighlights>().map_err(|e| e.to_string())?;
            if !h.radiance.is_empty() && h.radiance.len() != vertices {
                return Err(format!("the area-light highlights cover {} of {vertices} vertices", h.radiance.len()));
            }
        }
        let albedo = materials.iter().map(|m| m.material.albedo).collect();
        Ok(Self { irradiance, highlights, albedo, emitters, texels: None })
    }
}

/// The linked lights as one frame's [`AreaLightFrame`], once `area_irradiance` is evaluated, or
/// unshadowed from `area_preview` while it is not. A failed light is reported with its stage;
/// the frame draws without area lights.
pub(super) fn area_light_frame(
    evaluation: &crate::engine::Evaluation,
    lights: &[&crate::engine::GraphNode],
    output: &str,
    keyed: &dyn Fn(&str, &str) -> Result<Keyed, String>,
    materials: &[FrameMaterial],
    geometry: &Geometry,
    scene: &str,
) -> Result<Option<AreaLightFrame>, String> {
    let vertices = geometry.vertex_count();
    let ready = |stage: &str| evaluation.get(output, stage).is_some_and(|r| r.value.is_ok());
    // The preview stands in only while the traced light is still to come: a failed one is
    // reported, and nothing unshadowed is passed off as it.
    let pending = evaluation.get(output, "area_irradiance").is_none();
    let irradiance = match (ready("area_irradiance"), pending && ready("area_preview")) {
        _ if lights.is_empty() => return Ok(None),
        (true, _) => "area_irradiance",
        (false, true) => "area_preview",
        (false, false) => return Ok(None),
    };
    let mut emitters = Vec::new();
    for node in lights {
        let light = keyed(&node.id, "light")?;
        let light = light.value.expect::<AreaLight>().map_err(|e| e.to_string())?;
        emitters.push(light.emitter.clone());
    }
    // Highlights as last evaluated, for the Output's `highlight_eye` (the editor recomputes
    // them once its camera rests).
    let highlights = if ready("area_highlights") { Some(keyed(output, "area_highlights")?) } else { None };
    let mut frame = AreaLightFrame::new(keyed(output, irradiance)?, highlights, emitters, materials, vertices)?;
    // Per texel once traced (a later request tier), where any mesh has a texture.
    if ready("area_texel_irradiance") {
        let texels = keyed(scene, "texel_receivers")?;
        frame.texels = AreaTexels::new(&keyed(output, "area_texel_irradiance")?, &texels, geometry)?;
    }
    Ok(Some(frame))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::StageValue;
    use crate::kinds::output::area::AreaIrradiance;

    fn keyed(key: Key, value: StageValue) -> Keyed {
        Keyed { key, value: Arc::new(value) }
    }

    /// Each texel's irradiance lands in its mesh's layer at its own texel, vertices of meshes
    /// without a texture take layer -1, and a texel no triangle covers takes its neighbours'.
    #[test]
    fn texel_irradiance_is_laid_out_per_mesh_layer() {
        let mut floor = crate::mesh::plane(2.0, 4);
        floor.visibility_texture = true;
        let sphere = crate::mesh::sphere(0.5, 6);
        let meshes = crate::mesh::MeshSet { meshes: vec![sphere, floor] };
        let size = 8;
        let texels = crate::transport::TexelReceivers::rasterize(&meshes, size);
        assert!(!texels.texels.is_empty() && texels.texels.iter().all(|t| t.0 == 1));
        let irradiance: Vec<[f32; 3]> =
            texels.texels.iter().map(|&(_, x, y)| [f32::from(x), f32::from(y), 1.0]).collect();
        let geometry = Geometry::of_meshes(keyed(1, StageValue::new(meshes.clone())), vec![0, 0]).unwrap();
        let e = keyed(2, StageValue::new(AreaIrradiance { irradiance }));
        let t = AreaTexels::new(&e, &keyed(3, StageValue::new(texels.clone())), &geometry).unwrap().unwrap();
        assert_eq!((t.size, t.irradiance.len()), (size, size * size));
        for &(_, x, y) in &texels.texels {
            assert_eq!(t.irradiance[usize::from(y) * size + usize::from(x)], [f32::from(x), f32::from(y), 1.0, 0.0]);
        }
        let sphere_vertices = meshes.meshes[0].positions.len();
        assert!(t.vertex_layers[..sphere_vertices].iter().all(|&l| l == -1));
        assert!(t.vertex_layers[sphere_vertices..].iter().all(|&l| l == 0));
        assert_eq!(t.vertex_layers.len(), geometry.vertex_count());
        // Without a textured mesh there is nothing per texel.
        let none = crate::transport::TexelReceivers::rasterize(&crate::mesh::MeshSet { meshes: vec![] }, size);
        let empty = keyed(4, StageValue::new(AreaIrradiance::default()));
        assert!(AreaTexels::new(&empty, &keyed(5, StageValue::new(none)), &geometry).unwrap().is_none());
    }

    /// A lone covered texel spreads its value [`DILATION_RINGS`] rings out, and no further.
    #[test]
    fn uncovered_texels_take_their_covered_neighbours_mean() {
        let size = 12;
        let mut values = vec![[0.0f32; 4]; size * size];
        let mut covered = vec![false; size * size];
        values[0] = [2.0, 4.0, 6.0, 0.0];
        covered[0] = true;
        dilate(&mut values, &mut covered, size);
        for y in 0..size {
            for x in 0..size {
                let expected = if x.max(y) <= DILATION_RINGS { [2.0, 4.0, 6.0, 0.0] } else { [0.0; 4] };
                assert_eq!(values[y * size + x], expected, "({x}, {y})");
            }
        }
    }
}
