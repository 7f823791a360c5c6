//! The wavelet modes' relight on the CPU as stages ([`crate::triple_product::relight`]): what
//! a viewport on a CPU adapter uploads instead of running the relight kernel, where the
//! kernel is slower. As stages they are cached on everything they read (a rotation back is a
//! cache hit), run in the evaluation's worker and stop when it is cancelled. The result is
//! memoised on the values it depends on, so an edit upstream that changes none of them (an
//! albedo, the fog's phase) relights nothing. Big receiver sets read a pre-rotated lighting
//! table, memoised on the environment, so a rotation does not rebuild it.

use super::wavelet_grid;
use crate::engine::spec::StageSpec;
use crate::engine::{StageContext, StageError, StageValue};
use crate::triple_product::relight::{Relight, RelitReceivers, material_detail_weights};
use crate::triple_product::{BrdfTable, FrameTable, LocalVisibility, TexelVisibility};

/// The relit stage of a receiver set: the vertices' or the texels' (`wavelet_pixel`), lit by
/// the environment or, with the sun lit apart, by its residual.
pub fn stage_name(texels: bool, separate_sun: bool) -> &'static str {
    match (texels, separate_sun) {
        (false, false) => "wavelet_relit",
        (false, true) => "wavelet_residual_relit",
        (true, false) => "wavelet_texels_relit",
        (true, true) => "wavelet_texels_residual_relit",
    }
}

pub fn stages() -> Vec<StageSpec> {
    let spec = |name, stages, compute| StageSpec {
        name,
        version: 1,
        params: &["wavelet_terms", "wavelet_details"],
        stages,
        inputs: &[
            ("environment", "rotation"),
            ("scene", "receivers"),
            ("material", "local_table"),
            ("medium", "medium"),
        ],
        persist: None,
        compute,
    };
    vec![
        spec(stage_name(false, false), &["local_visibility", "wavelet_environment"], vertices),
        spec(stage_name(false, true), &["local_visibility", "wavelet_residual_environment"], residual_vertices),
        spec(stage_name(true, false), &["texel_visibility", "wavelet_environment"], texels),
        spec(stage_name(true, true), &["texel_visibility", "wavelet_residual_environment"], residual_texels),
    ]
}

fn vertices(ctx: &StageContext) -> Result<StageValue, StageError> {
    relit(ctx, false, "wavelet_environment")
}

fn residual_vertices(ctx: &StageContext) -> Result<StageValue, StageError> {
    relit(ctx, false, "wavelet_residual_environment")
}

fn texels(ctx: &StageContext) -> Result<StageValue, StageError> {
    relit(ctx, true, "wavelet_environment")
}

fn residual_texels(ctx: &StageContext) -> Result<StageValue, StageError> {
    relit(ctx, true, "wavelet_residual_environment")
}

/// One receiver set relit under `environment` (an own stage), as the frame's
/// `WaveletSurfaces` would relight it: the same cells, tables, detail weights and rotation.
fn relit(ctx: &StageContext, texels: bool, environment: &str) -> Result<StageValue, StageError> {
    let grid = wavelet_grid(ctx)?;
    let environment = ctx.stage::<crate::cubemap::CubeMap>(environment)?;
    let (receivers, visibility) = if texels {
        let t = ctx.stage::<TexelVisibility>("texel_visibility")?;
        (&t.receivers, &t.visibility)
    } else {
        (
            ctx.required_input::<crate::transport::Receivers>("scene", "receivers")?,
            ctx.stage::<LocalVisibility>("local_visibility")?,
        )
    };
    // Nothing to light: no environment, or no texel slot (the frame draws neither).
    if environment.size == 0 || receivers.is_empty() {
        return Ok(StageValue::new(RelitReceivers::default()));
    }
    let rotation = *ctx.required_input::<glam::DMat3>("environment", "rotation")?;
    let tables = ctx.inputs_all::<BrdfTable>("material", "local_table")?;
    let coarse: Vec<BrdfTable> = tables
        .iter()
        .map(|(_, t)| t.coarsened(grid.len()))
        .collect::<Result<_, String>>()
        .map_err(StageError::Failed)?;
    let Some(first) = coarse.first() else {
        return Err(StageError::Failed("the wavelet modes need a material: link a BRDF editor to the Output".into()));
    };
    // What reaches surfaces through fog scales each lobe's weight, as in the frame.
    let attenuation = ctx
        .input::<crate::kinds::fog::Medium>("medium", "medium")?
        .map_or([1.0; 3], |m| m.beta.map(|b| (-b * m.environment_distance).exp()));
    let details = material_detail_weights(grid, &coarse, attenuation, ctx.int("wavelet_details")?.max(0) as usize);
    let relight = Relight { grid, environment, rotation, diffuse_table: &first.diffuse, details: &details };
    let relit = ctx.memo(relight.content_key(receivers, visibility), || {
        let table = frame_table(ctx, &relight, receivers.len())?;
        relight.packed(receivers, visibility, table.as_deref(), ctx.cancel_token())
    })?;
    Ok(StageValue::new(RelitReceivers::clone(&relit)))
}

/// The pre-rotated lighting table where `receivers` many read one.
fn frame_table(
    ctx: &StageContext,
    relight: &Relight,
    receivers: usize,
) -> Result<Option<crate::engine::Memo<FrameTable>>, StageError> {
    let (grid, environment) = (relight.grid, relight.environment);
    Ok(if relight.uses_frame_table(receivers) {
        // Keyed on the environment's texels and the cells: rotations share it.
        const TAG: u64 = 0x7772_6c74_6162_6c65; // the table's memo, not another part's
        let key =
            xxhash_rust::xxh3::xxh3_128_with_seed(bytemuck::cast_slice(&environment.texels), TAG ^ grid.len() as u64);
        Some(ctx.memo(key, || Ok(FrameTable::build(grid, environment)))?)
    } else {
        None
    })
}
