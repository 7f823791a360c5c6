//! Materials whose highlight a mode cannot show as it is.

use super::*;

/// Materials whose highlight `mode` cannot show as it is, and why: irradiance shows no
/// highlights; SH of the Scene's order keeps less than half of a sharp lobe's energy
/// ([`crate::brdf::phong_sh_energy_kept`]); the wavelet table needs the lobe's half-maximum
/// cone to cover two of its cells ([`crate::brdf::sharpest_phong_for_cells`]), or with detail
/// terms two of the finest samples and the view step
/// ([`crate::triple_product::details::sharpest_phong_with_details`]).
pub(super) fn lobe_limits(
    graph: &Graph,
    output: &str,
    scene: &str,
    mode: Mode,
    materials: &[FrameMaterial],
    sun_apart: bool,
) -> Vec<(String, String)> {
    let int = |node: &str, name: &str, default: i64| match graph.node(node).and_then(|n| n.params.get(name)) {
        Some(ParamValue::Int(v)) => *v,
        _ => default,
    };
    let mut bands = int(scene, "transport_bands", 6).clamp(1, 16) as usize;
    if mode == Mode::ShAdaptive {
        // The glossy lobe is drawn at the adaptive level, within the environment's bands.
        let env = graph.upstream(output, "environment").map(|n| int(&n.id, "sh_bands", 6) as usize).unwrap_or(bands);
        bands = bands.min(env).min(int(output, "adaptive_level", 10) as usize + 1).clamp(1, 12);
    }
    let cells = match graph.node(output).and_then(|n| n.params.get("wavelet_terms")) {
        Some(ParamValue::Choice(c)) => c.parse().unwrap_or(320),
        _ => 320,
    };
    let sh_limit = crate::brdf::sharpest_phong_for_sh(bands, 0.5);
    let details = int(output, "wavelet_details", 32) > 0;
    let cell_limit = match details {
        true => crate::triple_product::details::sharpest_phong_with_details(cells),
        false => crate::brdf::sharpest_phong_for_cells(cells),
    };
    let shown_by = if details {
        format!("{cells} wavelet cells and their detail terms")
    } else {
        format!("{cells} wavelet cells")
    };
    let table_limit = crate::rsl::brdf_sat::sharpest_phong();
    let mut out = Vec::new();
    for m in materials.iter().filter(|m| !m.node.is_empty()) {
        let brdf = crate::brdf::Brdf::from_material(&m.material);
        let Some(exponent) = brdf.equivalent_phong_exponent() else { continue };
        if brdf.specular.max_element() * brdf.f0 <= 0.0 {
            continue;
        }
        let width = crate::brdf::phong_half_width(exponent).to_degrees();
        let lobe = format!("its {} highlight (about Phong {exponent:.0}, {width:.1}° half-width)", m.material.model);
        let message = match mode {
            Mode::ShIrradiance if sun_apart => Some(format!(
                "{mode} draws the sky's diffuse light and the sun's highlight: {lobe} shows the sun but not the \
                 sky; sh_prt shows lobes up to about Phong {sh_limit:.0}, the wavelet modes up to about Phong \
                 {cell_limit:.0}"
            )),
            Mode::ShIrradiance => Some(format!(
                "{mode} draws diffuse light only: {lobe} is not shown; sh_prt shows lobes up to about Phong \
                 {sh_limit:.0}, the wavelet modes up to about Phong {cell_limit:.0}"
            )),
            Mode::ShPrt | Mode::ShAdaptive if exponent > sh_limit => Some(format!(
                "{lobe} is sharper than {bands} SH bands show (about Phong {sh_limit:.0}): it is drawn broader and \
                 dimmer; raise the SH bands (the Scene's transport; in sh_adaptive also the environment's and the level), or use \
                 wavelet_pixel (to about Phong {cell_limit:.0})"
            )),
            Mode::WaveletVertex | Mode::WaveletPixel if exponent > cell_limit => Some(format!(
                "{lobe} is sharper than {shown_by} show (about Phong {cell_limit:.0}): it is drawn broader and \
                 dimmer than the reference"
            )),
            Mode::Rsl if exponent > table_limit => Some(format!(
                "{lobe} is sharper than the square lights' BRDF tables show (about Phong {table_limit:.0}): it is \
                 drawn broader and dimmer than the reference, and a square light's highlight is as large as the light"
            )),
            _ => None,
        };
        if let Some(message) = message {
            out.push((m.node.clone(), message));
        }
    }
    out
}
