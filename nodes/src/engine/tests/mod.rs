use super::*;
use crate::engine::spec::{Availability, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, StageSpec};
use crate::project::{Project, ProjectLink, ProjectNode, default_project};
use crate::scene_object::{SceneObject, Shape};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::sync::atomic::AtomicUsize;

mod adaptive_mode;
mod area_light_node;
mod blockers_mode;
mod disk_cache;
mod recompute;
mod relight;
mod rsl_mode;
mod spot_light_node;

fn default_graph() -> Graph {
    default_project().graph(Path::new("default.ron")).expect("default project is valid")
}

fn ran(report: &Report) -> BTreeSet<String> {
    report
        .stages
        .iter()
        .filter(|s| matches!(s.status, StageStatus::Computed | StageStatus::Failed))
        .map(|s| format!("{}.{}", s.node, s.stage))
        .collect()
}

/// A stage's value from an evaluation, as `T`.
fn value_of<T: StageType + Clone>(eval: &Evaluation, node: &str, stage: &str) -> T {
    eval.value(node, stage).unwrap().expect::<T>().unwrap().clone()
}

/// The default project's graph with a `kind` node `id` added and `links`
/// (`(from node, port, to node, port)`).
fn default_graph_with(id: &str, kind: &str, links: &[(&str, &str, &str, &str)]) -> Graph {
    let mut project = default_project();
    project.nodes.push(ProjectNode {
        id: id.into(),
        kind: kind.into(),
        label: String::new(),
        position: [0.0; 2],
        params: BTreeMap::new(),
    });
    project.links.extend(
        links
            .iter()
            .map(|(a, p, b, q)| ProjectLink { from: ((*a).into(), (*p).into()), to: ((*b).into(), (*q).into()) }),
    );
    project.graph(Path::new("p.ron")).unwrap()
}

/// What drawing the Output `output` needs, evaluated as the editor requests it, with no stage
/// failed.
fn evaluate_frame(engine: &Engine, graph: &Graph) -> Evaluation {
    let eval = engine.evaluate_request(
        graph,
        &crate::frame::frame_request(graph, "output", false),
        &CancelToken::default(),
        None,
        &|_, _| {},
    );
    assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
    eval
}

fn set(names: &[&str]) -> BTreeSet<String> {
    names.iter().map(|s| s.to_string()).collect()
}

fn report<'a>(eval: &'a Evaluation, node: &str, stage: &str) -> &'a crate::engine::StageReport {
    eval.report.stages.iter().find(|s| s.node == node && s.stage == stage).expect("stage in the report")
}

/// A stage's memoised parts, `(computed, reused)`, from its report line.
fn memo_parts(eval: &Evaluation, node: &str, stage: &str) -> (usize, usize) {
    let reasons = &report(eval, node, stage).reasons;
    let line = reasons.iter().find(|r| r.contains("part(s) computed")).expect("memoised parts");
    let numbers: Vec<usize> = line.split(' ').filter_map(|w| w.parse().ok()).collect();
    (numbers[0], numbers[1])
}

#[test]
fn environment_rotation_reports_why_and_reuses_the_projection() {
    let engine = Engine::in_memory();
    let mut graph = default_graph();
    engine.evaluate(&graph, &CancelToken::default(), None);
    graph.set_param("sky", "rotation", ParamValue::Vec3([0.0, 0.0, 45.0])).unwrap();
    let eval = engine.evaluate(&graph, &CancelToken::default(), None);
    let sh = eval.report.stages.iter().find(|s| s.node == "sky" && s.stage == "sh").unwrap();
    assert_eq!(sh.reasons, vec!["parameter `rotation` changed".to_string()]);
    let haar = eval.report.stages.iter().find(|s| s.node == "sky" && s.stage == "haar").unwrap();
    assert_eq!(haar.reasons, vec!["stage `rotated_radiance` changed".to_string()]);
    let projection = eval.report.stages.iter().find(|s| s.stage == "sh_unrotated").unwrap();
    assert_eq!(projection.status, StageStatus::MemoryHit);
    // Going back to the old value is a cache hit (undo costs nothing).
    graph.set_param("sky", "rotation", ParamValue::Vec3([0.0; 3])).unwrap();
    let back = engine.evaluate(&graph, &CancelToken::default(), None);
    assert!(ran(&back.report).is_empty(), "{:?}", ran(&back.report));
}

#[test]
fn rotated_sh_matches_projecting_the_rotated_cube_map() {
    // The `sh` stage rotates coefficients; projecting the resampled cube map must agree.
    let engine = Engine::in_memory();
    let mut graph = default_graph();
    graph.set_param("sky", "rotation", ParamValue::Vec3([70.0, 25.0, -10.0])).unwrap();
    graph.set_param("sky", "sun_size", ParamValue::Float(12.0)).unwrap();
    graph.set_param("sky", "resolution", ParamValue::Choice("128".into())).unwrap();
    let eval = engine.evaluate(&graph, &CancelToken::default(), None);
    let rotated = value_of::<crate::sh::ShRgb>(&eval, "sky", "sh");
    let cube = value_of::<crate::cubemap::CubeMap>(&eval, "sky", "rotated_radiance");
    let direct = crate::sh::project_samples(rotated.bands, cube.samples());
    let scale = direct.coeffs[0][0].abs();
    for (a, b) in rotated.coeffs.iter().zip(&direct.coeffs) {
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() < 0.02 * scale, "{a:?} vs {b:?}");
        }
    }
}

// ---- test kinds ------------------------------------------------------------------------

/// The test kinds' stage value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
struct Number(f64);
crate::stage_type!(Number, "number", encoding = 1, |_v| 64);

/// Only the disk-cache test uses the `Counted` kind, so its count is not raced by other tests.
static COUNTED_RUNS: AtomicUsize = AtomicUsize::new(0);

fn counted(ctx: &StageContext) -> Result<StageValue, StageError> {
    COUNTED_RUNS.fetch_add(1, Ordering::SeqCst);
    Ok(StageValue::new(Number(ctx.float("x")? * 2.0)))
}
static CONCURRENT: AtomicUsize = AtomicUsize::new(0);

fn expensive(ctx: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(Number(ctx.float("x")? * 2.0)))
}

fn slow(ctx: &StageContext) -> Result<StageValue, StageError> {
    // Runs until cancelled or 10 s pass.
    for i in 0..1000 {
        ctx.check_cancel()?;
        ctx.progress(i as f64 / 1000.0);
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    Ok(StageValue::new(Number(ctx.float("x")?)))
}

fn meet(ctx: &StageContext) -> Result<StageValue, StageError> {
    CONCURRENT.fetch_add(1, Ordering::SeqCst);
    let start = Instant::now();
    while CONCURRENT.load(Ordering::SeqCst) < 2 && start.elapsed().as_secs() < 5 {
        std::thread::yield_now();
    }
    Ok(StageValue::new(Number(if CONCURRENT.load(Ordering::SeqCst) >= 2 { 1.0 } else { 0.0 } + ctx.float("x")? * 0.0)))
}

fn fails(_: &StageContext) -> Result<StageValue, StageError> {
    Err(StageError::Failed("deliberate failure".into()))
}

fn sum(ctx: &StageContext) -> Result<StageValue, StageError> {
    let a = ctx.input::<Number>("a", "value")?.map_or(0.0, |n| n.0);
    Ok(StageValue::new(Number(a + ctx.float("x")?)))
}

fn test_kind(name: &'static str, compute: StageFn, persist: bool) -> NodeKindSpec {
    NodeKindSpec {
        name,
        label: name,
        doc: "test",
        inputs: vec![PortSpec { name: "a", ty: PortType::Medium, required: false, many: false }],
        outputs: vec![PortSpec { name: "out", ty: PortType::Medium, required: false, many: false }],
        params: vec![ParamSpec {
            name: "x",
            label: "x",
            unit: "",
            kind: ParamKind::Float { min: -1e9, max: 1e9, default: 1.0 },
            doc: "",
        }],
        stages: vec![StageSpec {
            name: "medium",
            version: 1,
            params: &["x"],
            stages: &[],
            inputs: &[("a", "value")],
            persist: persist.then(Codec::of::<Number>),
            compute,
        }],
        previews: Vec::new(),
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::engine::spec::no_referenced_files,
    }
}

use crate::engine::spec::StageFn;

/// SH with a NaN, an infinity and 1e38 among finite coefficients.
fn absurd(_: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(crate::sh::ShRgb {
        bands: 2,
        coeffs: vec![[1.0, f64::NAN, 2.0], [f64::INFINITY, 1e38, 0.5], [0.0; 3], [1e29; 3]],
    }))
}

#[test]
fn absurd_numbers_in_a_stage_output_are_reported_with_the_node() {
    let graph = test_graph(&[("broken", "Absurd"), ("down", "Sum")], &[("broken", "down")]);
    let eval = Engine::in_memory().evaluate(&graph, &CancelToken::default(), None);
    let stage = eval.report.stages.iter().find(|s| s.node == "broken").unwrap();
    assert_eq!(stage.warnings.len(), 1, "{:?}", stage.warnings);
    assert!(stage.warnings[0].starts_with("3 value(s) of its SH are NaN, infinite or beyond"), "{:?}", stage.warnings);
    assert!(eval.report.notes.iter().any(|n| n.starts_with("broken.value: 3 value(s)")), "{:?}", eval.report.notes);
}

fn test_registry() -> &'static [NodeKindSpec] {
    static REGISTRY: std::sync::OnceLock<Vec<NodeKindSpec>> = std::sync::OnceLock::new();
    REGISTRY.get_or_init(|| {
        let mut kinds = vec![
            test_kind("Expensive", expensive, true),
            test_kind("Counted", counted, true),
            test_kind("Slow", slow, false),
            test_kind("Meet", meet, false),
            test_kind("Fails", fails, false),
            test_kind("Sum", sum, false),
            test_kind("Absurd", absurd, false),
        ];
        for k in &mut kinds {
            // The test stages read their upstream stage as `value`.
            k.stages[0].name = "value";
        }
        kinds
    })
}

fn test_graph(nodes: &[(&str, &str)], links: &[(&str, &str)]) -> Graph {
    let params = BTreeMap::new();
    let inputs: Vec<graph::NodeInput> =
        nodes.iter().map(|(id, kind)| graph::NodeInput { id, kind, params: &params }).collect();
    let links: Vec<Link> = links
        .iter()
        .map(|(a, b)| Link {
            from_node: a.to_string(),
            from_port: "out".into(),
            to_node: b.to_string(),
            to_port: "a".into(),
        })
        .collect();
    Graph::build(&inputs, &links, PathBuf::from("."), test_registry()).unwrap()
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightloom-engine-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn disk_cache_serves_fresh_engines_and_recomputes_corrupt_entries() {
    let dir = temp_dir("disk");
    let config = || EngineConfig { memory_budget_bytes: 1 << 20, disk_cache: Some(dir.clone()), ..Default::default() };
    let mut graph = test_graph(&[("e", "Counted")], &[]);
    graph.set_param("e", "x", ParamValue::Float(21.0)).unwrap();
    let before = COUNTED_RUNS.load(Ordering::SeqCst);
    let first = Engine::new(config()).evaluate(&graph, &CancelToken::default(), None);
    assert_eq!(first.report.stages[0].status, StageStatus::Computed);
    let second = Engine::new(config()).evaluate(&graph, &CancelToken::default(), None);
    assert_eq!(second.report.stages[0].status, StageStatus::DiskHit);
    assert_eq!(second.value("e", "value").unwrap().get::<Number>(), Some(&Number(42.0)));
    assert_eq!(COUNTED_RUNS.load(Ordering::SeqCst) - before, 1);
    // Corrupt the entry: flip a payload byte; then truncate it.
    let path = Engine::new(config()).disk_cache().unwrap().path_for(first.results[0].key);
    for corrupt in [
        |b: &mut Vec<u8>| {
            let last = b.len() - 1;
            b[last] ^= 0xff;
        },
        |b: &mut Vec<u8>| b.truncate(b.len() / 2),
        |b: &mut Vec<u8>| b[0] = b'X',
    ] {
        let mut bytes = std::fs::read(&path).unwrap();
        corrupt(&mut bytes);
        std::fs::write(&path, &bytes).unwrap();
        let eval = Engine::new(config()).evaluate(&graph, &CancelToken::default(), None);
        let stage = &eval.report.stages[0];
        assert_eq!(stage.status, StageStatus::Computed, "corrupt entry must be recomputed");
        assert!(stage.reasons.iter().any(|r| r.contains("corrupt")), "{:?}", stage.reasons);
        assert_eq!(eval.value("e", "value").unwrap().get::<Number>(), Some(&Number(42.0)));
        // The recomputed entry replaced the corrupt one.
        let next = Engine::new(config()).evaluate(&graph, &CancelToken::default(), None);
        assert_eq!(next.report.stages[0].status, StageStatus::DiskHit);
    }
}

#[test]
fn cancellation_stops_running_stages_and_caches_nothing_partial() {
    let engine = Arc::new(Engine::in_memory());
    let graph = test_graph(&[("slow", "Slow"), ("after", "Sum")], &[("slow", "after")]);
    let job = engine.spawn(graph.clone());
    // Wait until the slow stage reports progress, then mark the evaluation stale.
    loop {
        match job.events.recv_timeout(std::time::Duration::from_secs(10)).expect("progress") {
            EvalEvent::StageProgress { .. } => break,
            _ => continue,
        }
    }
    let t = Instant::now();
    job.cancel();
    let eval = job.wait();
    assert!(t.elapsed().as_secs_f64() < 2.0, "cancellation took {:?}", t.elapsed());
    let statuses: Vec<StageStatus> = eval.report.stages.iter().map(|s| s.status).collect();
    assert_eq!(statuses, vec![StageStatus::Cancelled, StageStatus::Cancelled]);
    let key = eval.get("slow", "value").unwrap().key;
    assert!(!engine.memory.lock().unwrap().contains(key), "a cancelled stage left a cache entry");
    // A later evaluation of a different graph (x changed) is unaffected.
    let mut fast = test_graph(&[("e", "Expensive"), ("after", "Sum")], &[("e", "after")]);
    fast.set_param("after", "x", ParamValue::Float(0.5)).unwrap();
    let eval = engine.evaluate(&fast, &CancelToken::default(), None);
    assert!(eval.report.failed().is_empty());
    assert_eq!(eval.value("after", "value").unwrap().get::<Number>(), Some(&Number(2.5)));
}

#[test]
fn scheduler_cancels_the_stale_evaluation() {
    let engine = Arc::new(Engine::in_memory());
    let mut scheduler = Scheduler::default();
    scheduler.submit(&engine, test_graph(&[("slow", "Slow")], &[]));
    std::thread::sleep(std::time::Duration::from_millis(50));
    let t = Instant::now();
    scheduler.submit(&engine, test_graph(&[("e", "Expensive")], &[]));
    let eval = loop {
        if let Some(e) = scheduler.poll() {
            break e;
        }
        assert!(t.elapsed().as_secs() < 10, "the new evaluation never finished");
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    assert_eq!(eval.value("e", "value").unwrap().get::<Number>(), Some(&Number(2.0)));
}

#[test]
fn independent_stages_run_in_parallel_off_the_calling_thread() {
    let engine = Arc::new(Engine::in_memory());
    // Different parameters, so different keys (identical stages would share one computation).
    let mut graph = test_graph(&[("a", "Meet"), ("b", "Meet")], &[]);
    graph.set_param("b", "x", ParamValue::Float(2.0)).unwrap();
    let job = engine.spawn(graph);
    let eval = job.wait();
    assert_eq!(eval.value("a", "value").unwrap().get::<Number>(), Some(&Number(1.0)), "stages did not overlap");
    assert_eq!(eval.value("b", "value").unwrap().get::<Number>(), Some(&Number(1.0)));
}

#[test]
fn failures_propagate_downstream_and_leave_the_rest() {
    let engine = Engine::in_memory();
    let graph = test_graph(&[("bad", "Fails"), ("down", "Sum"), ("ok", "Sum")], &[("bad", "down")]);
    let eval = engine.evaluate(&graph, &CancelToken::default(), None);
    assert_eq!(eval.value("bad", "value").unwrap_err(), StageError::Failed("deliberate failure".into()));
    assert_eq!(eval.value("down", "value").unwrap_err(), StageError::Upstream("bad.value".into()));
    assert_eq!(eval.value("ok", "value").unwrap().get::<Number>(), Some(&Number(1.0)));
}

#[test]
fn memory_cache_stays_within_budget_evicting_least_recently_used() {
    let mut cache = MemoryCache::new(1000);
    let item = |v: f64| Arc::new(StageValue::new(Number(v))); // 128 bytes each
    for k in 0..7u128 {
        cache.insert(k, item(k as f64));
    }
    assert!(cache.get(0).is_some()); // touch 0 so 1 is the oldest
    cache.insert(7, item(7.0));
    cache.insert(8, item(8.0));
    assert!(cache.used_bytes() <= 1000);
    assert!(cache.get(0).is_some(), "recently used entry evicted");
    assert!(cache.get(1).is_none(), "least recently used entry kept");
    assert!(cache.get(8).is_some());
}

#[test]
fn validation_names_nodes_ports_and_parameters() {
    let mut project = default_project();
    project.nodes.push(ProjectNode {
        id: "mystery".into(),
        kind: "Teapot".into(),
        label: String::new(),
        position: [0.0; 2],
        params: BTreeMap::new(),
    });
    project.nodes[0].params.insert("exposure".into(), ParamValue::Float(1e9));
    project.nodes[0].params.insert("colour".into(), ParamValue::Float(1.0));
    project.nodes[2].params.insert("albedo".into(), ParamValue::Float(0.5));
    project
        .links
        .push(ProjectLink { from: ("sky".into(), "environment".into()), to: ("output".into(), "material".into()) });
    project.links.push(ProjectLink { from: ("ghost".into(), "x".into()), to: ("output".into(), "lights".into()) });
    project.links.retain(|l| l.to.1 != "scene");
    let errors = project.graph(Path::new("p.ron")).unwrap_err();
    let text: Vec<String> = errors.iter().map(|e| e.to_string()).collect();
    let has =
        |needle: &str| assert!(text.iter().any(|t| t.contains(needle)), "no error containing {needle:?} in {text:#?}");
    has("node `mystery`: unknown node kind `Teapot`");
    has("node `sky` parameter `exposure`: 1e9 EV is outside -20..=20");
    has("node `sky` parameter `colour`: EnvironmentMap has no such parameter");
    has("node `material` parameter `albedo`: expected Color, found Float");
    has("node `output` port `material`: expects Material, but `sky.environment` provides Environment");
    has("node `ghost` port `x`: link refers to a node that does not exist");
    has("node `output` port `scene`: required Scene input is not connected");
}

#[test]
fn cycles_are_reported_with_their_path() {
    let params = BTreeMap::new();
    let nodes: Vec<graph::NodeInput> =
        ["a", "b", "c"].iter().map(|id| graph::NodeInput { id, kind: "Sum", params: &params }).collect();
    let link = |a: &str, b: &str| Link {
        from_node: a.into(),
        from_port: "out".into(),
        to_node: b.into(),
        to_port: "a".into(),
    };
    let errors =
        Graph::build(&nodes, &[link("a", "b"), link("b", "c"), link("c", "a")], PathBuf::new(), test_registry())
            .unwrap_err();
    assert_eq!(errors.len(), 1);
    assert!(errors[0].message.starts_with("links form a cycle: "), "{}", errors[0]);
    for id in ["a", "b", "c"] {
        assert!(errors[0].message.contains(id));
    }
}

#[test]
fn project_ron_round_trips_and_migrates_version_one() {
    let project = default_project();
    let text = project.to_ron();
    let back = Project::from_ron(&text, Path::new("x.ron")).unwrap();
    assert_eq!(back, project);
    assert_eq!(back.to_ron(), text, "saving is deterministic");
    let v1 = r#"(
        version: 1,
        name: "old",
        camera: Some((eye: (0.0, 1.0, 5.0), look_at: (0.0, 0.0, 0.0), fov: 50.0)),
        nodes: [
            (id: "env", kind: "EnvironmentMap", pos: (10.0, 20.0), params: {"exposure": Float(1.5)}),
            (id: "geo", kind: "Scene"),
            (id: "out", kind: "Output"),
        ],
        links: ["env.environment -> out.environment", "geo.scene -> out.scene"],
    )"#;
    let migrated = Project::from_ron(v1, Path::new("old.ron")).unwrap();
    assert_eq!(migrated.version, crate::project::CURRENT_VERSION);
    assert_eq!(migrated.cameras[0].position, [0.0, 1.0, 5.0]);
    assert_eq!(migrated.nodes[0].position, [10.0, 20.0]);
    assert_eq!(migrated.links[1].from, ("geo".to_string(), "scene".to_string()));
    migrated.graph(Path::new("old.ron")).expect("migrated project is valid");
}

#[test]
fn saves_are_atomic_and_keep_a_backup() {
    let dir = temp_dir("save");
    let path = dir.join("scene.ron");
    let mut project = default_project();
    project.save(&path).unwrap();
    project.name = "second".into();
    project.save(&path).unwrap();
    let current = Project::from_ron(&std::fs::read_to_string(&path).unwrap(), &path).unwrap();
    let backup = Project::from_ron(&std::fs::read_to_string(dir.join("scene.ron.bak")).unwrap(), &path).unwrap();
    assert_eq!(current.name, "second");
    assert_eq!(backup.name, default_project().name);
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("tmp"))
        .collect();
    assert!(leftovers.is_empty());
    // Saving into a missing folder fails with a message naming the file, and the old file stays.
    let err = project.save(&dir.join("missing/x.ron")).unwrap_err().to_string();
    assert!(err.contains("missing/x.ron"), "{err}");
}

#[test]
fn a_stage_reading_the_wrong_type_gets_an_error_naming_both() {
    let value = StageValue::new(Number(1.0));
    let err = value.expect::<crate::sh::ShRgb>().unwrap_err();
    assert_eq!(err.to_string(), "internal error: expected SH, found number");
}

#[test]
fn scene_transport_stages_cover_every_receiver_and_follow_transforms() {
    use crate::kinds::scene::{SceneObject, Shape};
    let engine = Engine::in_memory();
    let mut graph = default_graph();
    let objects = vec![
        SceneObject::new("floor", Shape::Plane { size: 4.0 }),
        SceneObject::new("ball", Shape::Sphere { radius: 0.5 }).at([0.0, 0.5, 0.0]),
    ];
    graph.set_param("scene", "objects", ParamValue::Objects(objects.clone())).unwrap();
    graph.set_param("scene", "tessellation", ParamValue::Int(8)).unwrap();
    graph.set_param("scene", "transport_rays", ParamValue::Int(64)).unwrap();
    graph.set_param("scene", "haar_resolution", ParamValue::Choice("4".into())).unwrap();
    let eval = engine.evaluate(&graph, &CancelToken::default(), None);
    assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
    let r = value_of::<crate::transport::Receivers>(&eval, "scene", "receivers");
    let sh = value_of::<crate::transport::ShTransport>(&eval, "scene", "transport_sh");
    let haar = value_of::<crate::transport::HaarTransport>(&eval, "scene", "transport_haar");
    let local = value_of::<crate::transport::SphericalTransport>(&eval, "scene", "transport_local");
    assert_eq!(sh.visibility.len(), r.len() * 36);
    assert_eq!(haar.visibility.len(), r.len());
    assert_eq!(local.visibility.len(), r.len());
    // Floor receivers right under the ball are shadowed; far ones are not.
    let floor = 0..r.mesh_offsets[1];
    let v00 = |i: usize| sh.receiver(i).0[0];
    let under = floor
        .clone()
        .min_by(|&a, &b| {
            r.positions[a][0].hypot(r.positions[a][2]).total_cmp(&r.positions[b][0].hypot(r.positions[b][2]))
        })
        .unwrap();
    let corner = floor
        .clone()
        .max_by(|&a, &b| {
            r.positions[a][0].hypot(r.positions[a][2]).total_cmp(&r.positions[b][0].hypot(r.positions[b][2]))
        })
        .unwrap();
    assert!(v00(under) < v00(corner) - 0.5, "under the ball {} vs corner {}", v00(under), v00(corner));
    // Moving the ball moves its receivers by the same offset.
    let mut moved = objects;
    moved[1].translation = [1.0, 0.5, -0.5];
    graph.set_param("scene", "objects", ParamValue::Objects(moved)).unwrap();
    let eval2 = engine.evaluate(&graph, &CancelToken::default(), None);
    let r2 = value_of::<crate::transport::Receivers>(&eval2, "scene", "receivers");
    for i in r.mesh_offsets[1]..r.len() {
        let d = [0, 1, 2].map(|c| r2.positions[i][c] - r.positions[i][c]);
        assert!((d[0] - 1.0).abs() < 1e-5 && d[1].abs() < 1e-5 && (d[2] + 0.5).abs() < 1e-5, "{d:?}");
    }
}

#[test]
fn moving_a_rigid_object_reuses_every_per_object_transport() {
    use crate::kinds::scene::{SceneObject, Shape};
    let engine = Engine::in_memory();
    let mut graph = default_graph();
    let mut objects = vec![
        SceneObject::new("torus", Shape::Torus { major: 0.6, minor: 0.25 }),
        SceneObject::new("ball", Shape::Sphere { radius: 0.5 }).at([2.0, 0.5, 0.0]),
    ];
    graph.set_param("scene", "objects", ParamValue::Objects(objects.clone())).unwrap();
    graph.set_param("scene", "tessellation", ParamValue::Int(12)).unwrap();
    graph.set_param("scene", "transport_rays", ParamValue::Int(128)).unwrap();
    let stage = |eval: &Evaluation| eval.report.stages.iter().find(|s| s.stage == "transport_objects").unwrap().clone();
    let first = engine.evaluate(&graph, &CancelToken::default(), None);
    assert!(stage(&first).reasons.iter().any(|r| r == "2 part(s) computed, 0 reused"), "{:?}", stage(&first).reasons);
    let before = value_of::<Vec<crate::transport::ObjectTransport>>(&first, "scene", "transport_objects");
    // The torus self-shadows (its inner ring sees less sky than its outer rim); the ball does not.
    let v00 = |t: &crate::transport::ObjectTransport, i: usize| t.sh.receiver(i).0[0];
    let torus_min = (0..before[0].sh.visibility.len() / 36).map(|i| v00(&before[0], i)).fold(f32::MAX, f32::min);
    assert!(torus_min < 0.8 * (4.0 * std::f32::consts::PI).sqrt() / 2.0, "{torus_min}");
    // Move and rotate the ball: the stage reruns, but reuses both objects' transport.
    objects[1].translation = [-1.0, 0.5, 1.0];
    objects[1].rotation_deg = [0.0, 45.0, 0.0];
    graph.set_param("scene", "objects", ParamValue::Objects(objects.clone())).unwrap();
    let moved = engine.evaluate(&graph, &CancelToken::default(), None);
    assert_eq!(stage(&moved).status, StageStatus::Computed);
    assert!(stage(&moved).reasons.iter().any(|r| r == "0 part(s) computed, 2 reused"), "{:?}", stage(&moved).reasons);
    let after = value_of::<Vec<crate::transport::ObjectTransport>>(&moved, "scene", "transport_objects");
    assert_eq!(after[1].sh, before[1].sh);
    assert_ne!(after[1].world_from_object, before[1].world_from_object);
    // Changing the ball's shape recomputes only the ball.
    objects[1].shape = Shape::Sphere { radius: 0.7 };
    graph.set_param("scene", "objects", ParamValue::Objects(objects)).unwrap();
    let reshaped = engine.evaluate(&graph, &CancelToken::default(), None);
    assert!(
        stage(&reshaped).reasons.iter().any(|r| r == "1 part(s) computed, 1 reused"),
        "{:?}",
        stage(&reshaped).reasons
    );
}

#[test]
fn a_gltf_file_is_one_object_with_its_own_transport() {
    let file =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/gltf/assimp-glTF2/BoxTextured-glTF/BoxTextured.gltf");
    assert!(file.is_file(), "the repository's glTF assets are expected at {}", file.display());
    let engine = Engine::in_memory();
    let mut graph = default_graph();
    let model = SceneObject::new("box", Shape::Gltf { file: file.display().to_string() });
    graph.set_param("scene", "objects", ParamValue::Objects(vec![model])).unwrap();
    graph.set_param("scene", "transport_rays", ParamValue::Int(1024)).unwrap();
    let eval = engine.evaluate(&graph, &CancelToken::default(), None);
    assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
    let meshes = value_of::<crate::mesh::MeshSet>(&eval, "scene", "geometry");
    let objects = value_of::<Vec<crate::transport::ObjectTransport>>(&eval, "scene", "transport_objects");
    assert_eq!(objects.len(), 1);
    assert_eq!(objects[0].name, "box");
    let vertices: usize = meshes.meshes.iter().map(|m| m.positions.len()).sum();
    assert_eq!(objects[0].sh.visibility.len(), vertices * 36);
    // A convex box does not shadow itself: every receiver sees its whole upper hemisphere
    // (up to the Fibonacci quadrature: one ray stands for 4π/1024 sr).
    for i in 0..vertices {
        let v00 = objects[0].sh.receiver(i).0[0] as f64 * (4.0 * std::f64::consts::PI).sqrt();
        assert!((v00 - 2.0 * std::f64::consts::PI).abs() < 0.05, "receiver {i}: {v00}");
    }
}

#[test]
fn editing_a_gltf_buffer_file_changes_the_geometry_key() {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/gltf/assimp-glTF2/BoxTextured-glTF");
    let dir = temp_dir("gltf-sidecar");
    for name in ["BoxTextured.gltf", "BoxTextured0.bin"] {
        std::fs::copy(source.join(name), dir.join(name)).unwrap();
    }
    let engine = Engine::in_memory();
    let mut graph = default_graph();
    let model = SceneObject::new("box", Shape::Gltf { file: dir.join("BoxTextured.gltf").display().to_string() });
    graph.set_param("scene", "objects", ParamValue::Objects(vec![model])).unwrap();
    let geometry_key = |engine: &Engine, graph: &Graph| {
        let eval = engine.evaluate(graph, &CancelToken::default(), None);
        let report = eval.report.stages.iter().find(|s| s.node == "scene" && s.stage == "geometry").unwrap();
        (report.key, report.status)
    };
    let (first, _) = geometry_key(&engine, &graph);
    // Scale the first position by rewriting the buffer (same length, new content and mtime).
    let bin = dir.join("BoxTextured0.bin");
    let mut bytes = std::fs::read(&bin).unwrap();
    bytes.iter_mut().take(64).for_each(|b| *b ^= 0x01);
    std::thread::sleep(std::time::Duration::from_millis(20));
    std::fs::write(&bin, &bytes).unwrap();
    let (second, status) = geometry_key(&engine, &graph);
    assert_ne!(first, second, "the .bin next to the .gltf is part of the key");
    assert_eq!(status, StageStatus::Computed);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn repairs_are_reported_as_stage_warnings_even_on_cache_hits() {
    // An EXR with NaN and negative pixels: the environment loads, and its source stage says
    // what was repaired, on the first evaluation and on every reuse.
    let dir = temp_dir("nan-exr");
    let file = dir.join("bad.exr");
    exr::prelude::write_rgb_file(&file, 32, 16, |x, y| {
        if x == 3 && y < 4 {
            (f32::NAN, 1.0, 1.0)
        } else if x == 5 && y == 2 {
            (-2.0, 0.5, 0.5)
        } else {
            (1.0, 1.0, 1.0)
        }
    })
    .unwrap();
    let engine = Engine::in_memory();
    let mut graph = default_graph();
    graph.set_param("sky", "source", ParamValue::Choice("file".into())).unwrap();
    graph.set_param("sky", "file", ParamValue::Path(file.display().to_string())).unwrap();
    for round in 0..2 {
        let eval = engine.evaluate(&graph, &CancelToken::default(), None);
        assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
        let source = eval.report.stages.iter().find(|s| s.node == "sky" && s.stage == "source").unwrap();
        assert_eq!(source.status, if round == 0 { StageStatus::Computed } else { StageStatus::MemoryHit });
        assert_eq!(source.warnings.len(), 1, "{:?}", source.warnings);
        assert!(source.warnings[0].contains("5 pixel(s) had NaN"), "{}", source.warnings[0]);
        assert!(eval.report.notes.iter().any(|n| n.starts_with("sky.source: ")), "{:?}", eval.report.notes);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---- demand-driven evaluation ----------------------------------------------------------

/// The default graph, cheap enough to evaluate every mode in a test.
fn small_default_graph() -> Graph {
    let mut graph = default_graph();
    graph.set_param("scene", "tessellation", ParamValue::Int(12)).unwrap();
    graph.set_param("scene", "transport_rays", ParamValue::Int(32)).unwrap();
    graph.set_param("scene", "local_frame_depth", ParamValue::Int(2)).unwrap();
    graph.set_param("scene", "visibility_texture_size", ParamValue::Choice("16".into())).unwrap();
    graph
}

#[test]
fn edits_the_current_view_does_not_read_schedule_nothing() {
    use crate::frame::frame_request;
    use ParamValue::*;
    let engine = Engine::in_memory();
    let mut graph = small_default_graph();
    graph.set_param("output", "mode", Choice("sh_irradiance".into())).unwrap();
    let run = |graph: &Graph| {
        let request = frame_request(graph, "output", false);
        engine.evaluate_request(graph, &request, &CancelToken::default(), None, &|_, _| {})
    };
    run(&graph);
    for (node, param, value) in [
        ("scene", "transport_rays", Int(64)),
        ("scene", "transport_bands", Int(4)),
        ("scene", "haar_terms", Int(64)),
        ("scene", "local_frame_terms", Int(80)),
        ("scene", "visibility_texture_size", Choice("32".into())),
        ("sky", "wavelet_terms", Int(64)),
        ("output", "wavelet_terms", Choice("80".into())),
    ] {
        graph.set_param(node, param, value).unwrap();
        let eval = run(&graph);
        assert!(ran(&eval.report).is_empty(), "{node}.{param} ran {:?}", ran(&eval.report));
    }
    // Switching the mode pulls only what the new mode lacks: sh_prt's transport and products
    // (no prefiltered light: the material is Lambert).
    graph.set_param("output", "mode", Choice("sh_prt".into())).unwrap();
    assert_eq!(
        ran(&run(&graph).report),
        set(&[
            "output.settings",
            "scene.receivers",
            "scene.ray_scene",
            "scene.transport_sh",
            "material.sh_lobe",
            "output.blocked_transport",
            "output.incident_residual_sh"
        ])
    );
    // And switching back is free: every stage it reads is still in the memory cache.
    graph.set_param("output", "mode", Choice("sh_irradiance".into())).unwrap();
    assert!(ran(&run(&graph).report).is_empty());
}

#[test]
fn the_first_evaluation_shows_an_unshadowed_frame_before_the_transport_then_a_shadowed_one() {
    use crate::frame::{FrameInputs, frame_request};
    use crate::kinds::output::Mode;
    let engine = Arc::new(Engine::in_memory());
    let graph = default_graph();
    let request = frame_request(&graph, "output", true);
    assert_eq!(request.tiers.len(), 2, "a shadowed default mode gets an unshadowed tier first");
    let job = engine.spawn_request(graph.clone(), request);
    let mut tiers = Vec::new();
    for event in job.events.iter() {
        match event {
            EvalEvent::TierReady { tier, .. } => tiers.push(tier),
            EvalEvent::Finished => break,
            _ => {}
        }
    }
    assert_eq!(tiers, [0]);
    let (_, partial) = job.take_partial().expect("the preview tier's evaluation");
    let transport = partial.report.stages.iter().find(|s| s.stage.starts_with("transport_"));
    assert!(transport.is_none(), "the preview is ready before the transport runs: {transport:?}");
    let preview = FrameInputs::gather(&partial, &graph, "output").unwrap();
    assert_eq!((preview.mode, preview.settings.mode), (Mode::ShIrradiance, Mode::WaveletPixel));
    assert!(preview.pending.as_deref().is_some_and(|p| p.contains("unshadowed")), "{:?}", preview.pending);
    assert!(matches!(preview.surfaces, crate::frame::Surfaces::Irradiance(_)) && preview.ray_scene.is_some());
    let done = job.wait();
    let shadowed = FrameInputs::gather(&done, &graph, "output").unwrap();
    assert_eq!(shadowed.mode, Mode::WaveletPixel);
    let per_texel = matches!(&shadowed.surfaces, crate::frame::Surfaces::Wavelet(w) if w.texels.is_some());
    assert!(shadowed.pending.is_none() && per_texel, "the shadowed frame draws per texel");
}

/// Transport parameters at their documented maxima once ran for minutes and took gigabytes;
/// beyond the rays budget the precompute is refused at once, with the estimate and what to
/// lower.
#[test]
fn transport_beyond_the_rays_budget_is_refused_with_its_estimate() {
    let mut graph = default_graph();
    // About 70k receivers: enough to exceed the budget at 65536 rays, cheap to mesh.
    graph.set_param("scene", "tessellation", ParamValue::Int(200)).unwrap();
    graph.set_param("scene", "transport_rays", ParamValue::Int(65536)).unwrap();
    let request = Request::new("sh transport", vec![StageRef::new("scene", "transport_sh")]);
    let eval = Engine::in_memory().evaluate_request(&graph, &request, &CancelToken::default(), None, &|_, _| {});
    let failed = eval.report.failed();
    let stage = failed.iter().find(|s| s.stage == "transport_sh").expect("transport_sh is refused");
    let error = stage.error.as_deref().unwrap_or_default();
    assert!(error.contains("visibility rays") && error.contains("lower transport_rays or tessellation"), "{error}");
}

/// An edit during a long stage (here one downstream of it) does not restart that stage: the
/// newer evaluation joins the computation already running, sees its progress, and gets its
/// result. `Slow` takes 10 s; restarting it would take at least 10 s more.
#[test]
fn a_newer_evaluation_joins_a_stage_already_running() {
    let engine = Arc::new(Engine::in_memory());
    let graph = test_graph(&[("slow", "Slow"), ("after", "Sum")], &[("slow", "after")]);
    let older = engine.spawn(graph.clone());
    let started = Instant::now();
    // Let the slow stage get a third of the way, then edit: the older evaluation is cancelled.
    std::thread::sleep(std::time::Duration::from_millis(3500));
    let mut edited = graph.clone();
    edited.set_param("after", "x", ParamValue::Float(0.5)).unwrap();
    let newer = engine.spawn(edited);
    older.cancel();
    std::thread::spawn(move || drop(older.wait()));
    let mut joined_at = None;
    while !newer.is_finished() {
        while let Ok(event) = newer.events.try_recv() {
            if let EvalEvent::StageProgress { node, fraction, .. } = event
                && node == "slow"
                && joined_at.is_none()
            {
                joined_at = Some(fraction);
            }
        }
        assert!(started.elapsed().as_secs() < 30, "the newer evaluation never finished");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let eval = newer.wait();
    let total = started.elapsed().as_secs_f64();
    assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
    assert_eq!(eval.value("after", "value").unwrap().get::<Number>(), Some(&Number(1.5)));
    let slow_alone = eval.report.stages.iter().find(|s| s.node == "slow").unwrap().ms / 1e3;
    assert!(
        slow_alone < total - 2.0,
        "the newer evaluation waited {slow_alone:.1} s of the {total:.1} s: it restarted"
    );
    let joined_at = joined_at.expect("the newer evaluation reported the stage's progress");
    assert!(joined_at > 0.2, "progress continued from where it was, not from 0 ({joined_at:.2})");
    let slow = eval.report.stages.iter().find(|s| s.node == "slow").unwrap();
    assert!(slow.reasons.iter().any(|r| r.contains("joined")), "{:?}", slow.reasons);
}
