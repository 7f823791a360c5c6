//! The wavelet modes' CPU relight as engine stages: what a viewport on a CPU adapter uploads
//! instead of running its kernel.

use super::*;
use crate::frame::{FrameInputs, FrameNeeds, Surfaces, WaveletSurfaces, frame_request_for};
use crate::triple_product::packing::rgb9e5_decode;
use crate::triple_product::relight::RelitReceivers;

fn wavelet_frame(engine: &Engine, graph: &Graph, relight_on_cpu: bool) -> (Evaluation, Box<WaveletSurfaces>) {
    let request = frame_request_for(graph, "output", FrameNeeds { picking: false, relight_on_cpu });
    let eval = engine.evaluate_request(graph, &request, &CancelToken::default(), None, &|_, _| {});
    assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
    let frame = FrameInputs::gather(&eval, graph, "output").unwrap();
    let Surfaces::Wavelet(data) = frame.surfaces else { panic!("not a wavelet frame") };
    (eval, data)
}

/// [`small_default_graph`] seen through the default fog.
fn fogged_graph() -> Graph {
    let mut project = default_project();
    let params = std::collections::BTreeMap::new();
    project.nodes.push(ProjectNode {
        id: "fog".into(),
        kind: "FogMedium".into(),
        label: String::new(),
        position: [0.0; 2],
        params,
    });
    project.links.push(ProjectLink { from: ("fog".into(), "medium".into()), to: ("output".into(), "medium".into()) });
    let mut graph = project.graph(Path::new("fogged.ron")).unwrap();
    for (param, value) in [
        ("tessellation", ParamValue::Int(12)),
        ("transport_rays", ParamValue::Int(32)),
        ("local_frame_depth", ParamValue::Int(2)),
        ("visibility_texture_size", ParamValue::Choice("16".into())),
    ] {
        graph.set_param("scene", param, value).unwrap();
    }
    graph
}

/// Each relit set decodes to the frame's own CPU twin (its products within RGB9E5's precision,
/// its diffuse transfer exactly): the stages read the cells, tables, detail weights and
/// rotation the frame does, in both wavelet modes, with the sun lit apart or not, through fog.
#[test]
fn the_relit_stages_are_the_frames_own_relight() {
    use ParamValue::Choice;
    let engine = Engine::in_memory();
    for (mode, sun, fog) in [
        ("wavelet_vertex", "separate", false),
        ("wavelet_vertex", "in_environment", true),
        ("wavelet_pixel", "separate", false),
    ] {
        let mut graph = if fog { fogged_graph() } else { small_default_graph() };
        graph.set_param("output", "mode", Choice(mode.into())).unwrap();
        graph.set_param("output", crate::kinds::output::SUN, Choice(sun.into())).unwrap();
        graph.set_param("output", "wavelet_details", ParamValue::Int(4)).unwrap();
        let (_, plain) = wavelet_frame(&engine, &graph, false);
        assert!(plain.relit.is_none(), "{mode}: relit without being asked");
        let (_, data) = wavelet_frame(&engine, &graph, true);
        let relit = data.relit.as_ref().unwrap_or_else(|| panic!("{mode}: not relit"));
        assert_eq!(relit.texels.is_some(), mode == "wavelet_pixel", "{mode}");
        let sets = std::iter::once((&data.vertices, &relit.vertices)).chain(data.texels.iter().zip(&relit.texels));
        for (set, keyed) in sets {
            let relit = keyed.value.expect::<RelitReceivers>().unwrap();
            let (products, details) = data.cpu_products_of(set, None, &CancelToken::default()).unwrap();
            assert_eq!(relit.products.len() * 3, products.values.len(), "{mode}");
            for (packed, rgb) in relit.products.iter().zip(products.values.chunks_exact(3)) {
                let decoded = rgb9e5_decode(*packed);
                let max = rgb[0].max(rgb[1]).max(rgb[2]);
                assert!((0..3).all(|c| (decoded[c] - rgb[c]).abs() <= max / 256.0 + 1e-12), "{mode}: {rgb:?}");
            }
            let transfer = crate::triple_product::diffuse_transfer(&products, &data.diffuse_table);
            assert!(relit.irradiance.iter().zip(&transfer).all(|(a, b)| a[..3] == b[..]), "{mode}");
            assert_eq!(details.kept > 0, !relit.details.is_empty(), "{mode}");
            assert_eq!(relit.details.len(), details.nodes.len() * 5, "{mode}");
        }
    }
}

/// A rotation relights from the cached visibility and environment; an unchanged graph
/// relights nothing, and an albedo edit reruns the stage but reuses its relight (the products
/// do not depend on it).
#[test]
fn a_rotation_relights_from_the_cached_visibility() {
    let engine = Engine::in_memory();
    let mut graph = small_default_graph();
    graph.set_param("output", "mode", ParamValue::Choice("wavelet_vertex".into())).unwrap();
    let relit = |eval: &Evaluation| value_of::<RelitReceivers>(eval, "output", "wavelet_residual_relit");
    let (first, _) = wavelet_frame(&engine, &graph, true);
    let (again, _) = wavelet_frame(&engine, &graph, true);
    assert!(ran(&again.report).is_empty(), "{:?}", ran(&again.report));
    let parts = |eval: &Evaluation| {
        let stage = eval.report.stages.iter().find(|s| s.stage == "wavelet_residual_relit").unwrap();
        stage.reasons.iter().find(|r| r.contains("part(s)")).cloned().unwrap_or_default()
    };
    graph.set_param("material", "albedo", ParamValue::Color([0.3, 0.5, 0.2])).unwrap();
    let (recoloured, _) = wavelet_frame(&engine, &graph, true);
    assert!(ran(&recoloured.report).contains("output.wavelet_residual_relit"));
    assert_eq!(parts(&recoloured), "0 part(s) computed, 1 reused");
    graph.set_param("sky", "rotation", ParamValue::Vec3([0.0, 60.0, 0.0])).unwrap();
    let (turned, _) = wavelet_frame(&engine, &graph, true);
    let rerun = ran(&turned.report);
    assert_eq!(parts(&turned), "1 part(s) computed, 0 reused");
    assert!(rerun.contains("output.wavelet_residual_relit"), "{rerun:?}");
    for cached in ["output.local_visibility", "output.wavelet_residual_environment", "scene.transport_local"] {
        assert!(!rerun.contains(cached), "{cached} reran: {rerun:?}");
    }
    assert_ne!(relit(&first).products, relit(&turned).products, "the products turned with the sky");
}

/// The relight stops when its evaluation is cancelled.
#[test]
fn a_cancelled_relight_stops() {
    use crate::triple_product::details::DetailWeights;
    use crate::triple_product::relight::Relight;
    use crate::triple_product::{CellGrid, LocalVisibility};
    let grid = CellGrid::for_coefficients(80).unwrap();
    let mesh = crate::mesh::sphere(1.0, 8);
    let receivers = crate::transport::Receivers::from_meshes(&crate::mesh::MeshSet { meshes: vec![mesh] });
    let visibility = LocalVisibility { cells: grid.len(), values: vec![1.0; grid.len() * receivers.len()] };
    let environment = crate::cubemap::CubeMap { size: 4, texels: vec![[1.0; 3]; 6 * 16] };
    let details = DetailWeights::default();
    let diffuse = vec![0.1; grid.len()];
    let relight = Relight {
        grid,
        environment: &environment,
        rotation: glam::DMat3::IDENTITY,
        diffuse_table: &diffuse,
        details: &details,
    };
    let cancel = CancelToken::default();
    assert!(relight.packed(&receivers, &visibility, None, &cancel).is_ok());
    cancel.cancel();
    assert_eq!(relight.packed(&receivers, &visibility, None, &cancel), Err(StageError::Cancelled));
}
