//! The environment in a frame: its SH light, its rotated radiance behind the scene, and its
//! sun when the Output lights it apart from the mode's transport.

use super::gather::{Gather, MaterialParts};
use super::modes::Linked;
use super::parts::{Assembled, FramePart};
use super::*;

/// The environment linked to the Output.
pub(super) struct Environment;

impl FramePart for Environment {
    fn port(&self) -> &'static str {
        "environment"
    }

    fn stages(&self, node: &str, linked: &Linked) -> Vec<StageRef> {
        let mut stages = vec![StageRef::new(node, "sh"), StageRef::new(node, "rotated_radiance")];
        if linked.separate_sun {
            stages.extend(["sun", "residual_sh", "rotation"].map(|s| StageRef::new(node, s)));
        }
        stages
    }

    fn gather(&self, g: &Gather, node: &str, _: &MaterialParts, frame: &mut Assembled) -> Result<(), String> {
        let sh = g.keyed(node, "sh")?;
        frame.radiance = Some(g.keyed(node, "rotated_radiance")?);
        // With the sun lit apart, the transport carries the sky without it.
        if g.separate_sun {
            let split = g.keyed(node, "sun")?;
            let split = split.value.expect::<crate::sun::SunSplit>().map_err(|e| e.to_string())?;
            let rotation = *g.keyed(node, "rotation")?.value.expect::<glam::DMat3>().map_err(|e| e.to_string())?;
            frame.sun = split.sun.map(|s| SunFrame::new(&s.rotated(rotation)));
            frame.lighting_sh = Some(g.keyed(node, "residual_sh")?);
        } else {
            frame.lighting_sh = Some(sh.clone());
        }
        // Requested after the frame's own stages (`request`): absent until prefiltered.
        frame.lighting_cube = g.keyed(node, &highlight_cube(node, g.separate_sun).stage).ok();
        frame.sh = Some(sh);
        Ok(())
    }
}

/// The stage of environment `node` that holds the light the transport carries (the sky alone
/// with the sun lit apart), GGX-prefiltered: per-vertex highlights on normal-mapped surfaces
/// are corrected through it.
pub(super) fn highlight_cube(node: &str, separate_sun: bool) -> StageRef {
    StageRef::new(node, if separate_sun { "residual_highlight_cube" } else { "highlight_cube" })
}
