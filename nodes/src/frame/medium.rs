//! Point lights and the participating medium in a frame (Sun 2008 ch. 3).

use super::gather::{Gather, MaterialParts};
use super::modes::Linked;
use super::parts::{Assembled, FramePart};
use super::*;

/// The participating medium linked to the Output (read after the environment, whose light it
/// carries through the fog).
pub(super) struct Medium;

impl FramePart for Medium {
    fn port(&self) -> &'static str {
        "medium"
    }

    fn stages(&self, node: &str, _: &Linked) -> Vec<StageRef> {
        ["medium", "f_tables", "g_tables"].map(|s| StageRef::new(node, s)).to_vec()
    }

    fn gather(&self, g: &Gather, node: &str, _: &MaterialParts, frame: &mut Assembled) -> Result<(), String> {
        if frame.sh.is_none() && g.upstream("environment").is_some() {
            return Err(
                "the medium was gathered before the environment whose light it carries (frame::parts::PARTS)".into()
            );
        }
        frame.fog = Some(fog_frame(g, node, frame.sh.as_ref())?);
        Ok(())
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

/// The medium linked to the Output as one frame's [`FogFrame`].
fn fog_frame(g: &Gather, node: &str, sh: Option<&Keyed>) -> Result<FogFrame, String> {
    let keyed = |node: &str, stage: &str| g.keyed(node, stage);
    let m: crate::kinds::fog::Medium = typed(&keyed(node, "medium")?, "medium")?;
    let phase = m.phase_function().ok_or_else(|| format!("{node}: the phase polynomial is invalid"))?;
    let f_tables = keyed(node, "f_tables")?;
    let environment = match sh {
        Some(sh) => {
            let tables = f_tables.value.expect::<Vec<crate::single_scattering::FTable>>().map_err(|e| e.to_string())?;
            let light = sh.value.expect::<crate::sh::ShRgb>().map_err(|e| e.to_string())?;
            Some(crate::single_scattering::FoggedEnvironment::new(
                m.beta,
                m.environment_distance,
                &phase,
                tables,
                light,
            ))
        }
        None => None,
    };
    Ok(FogFrame {
        beta: m.beta,
        phase: phase.weights,
        f_tables,
        g_tables: keyed(node, "g_tables")?,
        environment,
        scatter_onto_surfaces: g.mode.is_wavelet(),
    })
}
