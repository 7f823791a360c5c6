//! Engine overhead: incremental re-evaluation of a 200-node graph with no-op stages after one
//! parameter change. Run with `cargo bench -p lightloom-nodes --bench engine`.

use criterion::{Criterion, criterion_group, criterion_main};
use lightloom_nodes::engine::graph::NodeInput;
use lightloom_nodes::engine::spec::{
    Availability, NodeKindSpec, ParamKind, ParamSpec, ParamValue, PortSpec, PortType, StageSpec,
};
use lightloom_nodes::engine::{
    CancelToken, Engine, Graph, Link, Request, StageContext, StageError, StageRef, StageValue,
};
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Debug)]
struct Unit;
lightloom_nodes::stage_type!(Unit, "unit");

fn noop(_: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(Unit))
}

fn registry() -> &'static [NodeKindSpec] {
    let stage = |name, stages: &'static [&'static str], inputs: &'static [(&'static str, &'static str)]| StageSpec {
        name,
        version: 1,
        params: &["x"],
        stages,
        inputs,
        persist: None,
        compute: noop,
    };
    Box::leak(Box::new([NodeKindSpec {
        name: "Noop",
        label: "no-op",
        doc: "",
        inputs: vec![PortSpec { name: "in", ty: PortType::Medium, required: false, many: false }],
        outputs: vec![PortSpec { name: "medium", ty: PortType::Medium, required: false, many: false }],
        params: vec![ParamSpec {
            name: "x",
            label: "x",
            unit: "",
            kind: ParamKind::Float { min: -1e12, max: 1e12, default: 0.0 },
            doc: "",
        }],
        stages: vec![stage("a", &[], &[("in", "medium")]), stage("b", &["a"], &[]), stage("medium", &["b"], &[])],
        previews: Vec::new(),
        gizmo: lightloom_nodes::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: lightloom_nodes::engine::spec::always_relevant,
        groups: &[],
        referenced_files: lightloom_nodes::engine::spec::no_referenced_files,
    }]))
}

/// 200 nodes: a binary tree of links (node i reads node (i-1)/2), three stages each.
fn graph(registry: &'static [NodeKindSpec]) -> Graph {
    let ids: Vec<String> = (0..200).map(|i| format!("n{i}")).collect();
    let params = BTreeMap::new();
    let nodes: Vec<NodeInput> = ids.iter().map(|id| NodeInput { id, kind: "Noop", params: &params }).collect();
    let links: Vec<Link> = (1..200)
        .map(|i| Link {
            from_node: ids[(i - 1) / 2].clone(),
            from_port: "medium".into(),
            to_node: ids[i].clone(),
            to_port: "in".into(),
        })
        .collect();
    Graph::build(&nodes, &links, PathBuf::new(), registry).expect("valid graph")
}

fn incremental(c: &mut Criterion) {
    let registry = registry();
    let mut graph = graph(registry);
    let engine = Engine::in_memory();
    engine.evaluate(&graph, &CancelToken::default(), None);
    let mut counter = 0.0;
    // A leaf change dirties 3 stages; the root change dirties all 600.
    c.bench_function("engine_200_nodes_leaf_change", |b| {
        b.iter(|| {
            counter += 1.0;
            graph.set_param("n199", "x", ParamValue::Float(counter)).unwrap();
            engine.evaluate(&graph, &CancelToken::default(), None)
        })
    });
    // Pulled: only what one leaf's output reads (its 3 stages and its 7 ancestors' 21).
    let leaf = Request::new("leaf", vec![StageRef::new("n199", "medium")]);
    c.bench_function("engine_200_nodes_leaf_change_requested", |b| {
        b.iter(|| {
            counter += 1.0;
            graph.set_param("n199", "x", ParamValue::Float(counter)).unwrap();
            engine.evaluate_request(&graph, &leaf, &CancelToken::default(), None, &|_, _| {})
        })
    });
    c.bench_function("engine_200_nodes_no_change", |b| {
        b.iter(|| engine.evaluate(&graph, &CancelToken::default(), None))
    });
    c.bench_function("engine_200_nodes_root_change", |b| {
        b.iter(|| {
            counter += 1.0;
            graph.set_param("n0", "x", ParamValue::Float(counter)).unwrap();
            engine.evaluate(&graph, &CancelToken::default(), None)
        })
    });
}

criterion_group!(benches, incremental);
criterion_main!(benches);
