//! The disk cache: its entry format, type and encoding checks, size checks, budget and
//! pruning, and memoised parts.

use super::*;

#[test]
fn persisted_stage_values_round_trip_through_the_disk_format() {
    use crate::transport::{HaarTransport, ShTransport, SphericalTransport};
    use crate::wavelet::SparseVector;
    fn round_trip<T: Persisted + PartialEq + Clone>(disk: &cache::DiskCache, key: Key, value: T) {
        let codec = Codec::of::<T>();
        disk.store(key, &StageValue::new(value.clone()), &codec).unwrap();
        match disk.load(key, &codec) {
            cache::DiskLookup::Hit(back) => assert_eq!(back.get::<T>(), Some(&value), "{}", T::NAME),
            _ => panic!("{} did not round-trip", T::NAME),
        }
    }
    let dir = temp_dir("roundtrip");
    let disk = cache::DiskCache::new(&dir);
    round_trip(&disk, 0, Number(1.5));
    round_trip(&disk, 1, ShTransport { bands: 2, rays: 16, visibility: vec![1.0; 8], transfer: vec![0.5; 8] });
    round_trip(
        &disk,
        2,
        HaarTransport {
            size: 4,
            keep: 2,
            visibility: vec![SparseVector { entries: vec![(0, 1.0), (7, -0.5)] }],
            transfer: vec![SparseVector::default()],
        },
    );
    round_trip(
        &disk,
        3,
        SphericalTransport { depth: 1, keep: 3, visibility: vec![SparseVector { entries: vec![(3, 2.0)] }] },
    );
}

/// A value type whose encoding changed: same name, a new `ENCODING`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct NumberV2(f64, f64);
impl StageType for NumberV2 {
    const NAME: &'static str = "number";
}
impl Persisted for NumberV2 {
    const ENCODING: u32 = 2;
}

#[test]
fn the_disk_cache_stays_within_its_budget_and_drops_the_least_recently_used_first() {
    let dir = temp_dir("prune");
    let entry = |n: f64| StageValue::new(NumberV2(n, n));
    let codec = Codec::of::<NumberV2>();
    // Ten entries, written one second apart in the past (oldest first).
    let unbounded = cache::DiskCache::new(&dir);
    let start = std::time::SystemTime::now() - std::time::Duration::from_secs(100);
    for k in 0..10u128 {
        unbounded.store(k, &entry(k as f64), &codec).unwrap();
        let file = std::fs::OpenOptions::new().append(true).open(unbounded.path_for(k)).unwrap();
        file.set_modified(start + std::time::Duration::from_secs(k as u64)).unwrap();
    }
    let size = std::fs::metadata(unbounded.path_for(0)).unwrap().len();
    // Reading entry 1 makes it the most recently used.
    assert!(matches!(unbounded.load(1, &codec), cache::DiskLookup::Hit(_)));
    // Opening the cache with room for four entries keeps the four most recently used.
    let bounded = cache::DiskCache::with_budget(&dir, 4 * size + size / 2);
    let kept: Vec<u128> = (0..10).filter(|k| bounded.path_for(*k).exists()).collect();
    assert_eq!(kept, vec![1, 7, 8, 9]);
    let report = bounded.prune().unwrap();
    assert_eq!(report, cache::PruneReport { kept_bytes: 4 * size, removed_entries: 0, removed_bytes: 0 });
    // Writing past an eighth of the budget prunes again: the total never grows past it.
    for k in 10..40u128 {
        bounded.store(k, &entry(k as f64), &codec).unwrap();
        let total: u64 = (0..=k).filter_map(|k| std::fs::metadata(bounded.path_for(k)).ok()).map(|m| m.len()).sum();
        assert!(total <= 4 * size + size / 2 + size, "{total} bytes after writing entry {k}");
    }
}

#[test]
fn a_huge_file_in_place_of_an_entry_is_rejected_without_reading_it() {
    let dir = temp_dir("huge-entry");
    let disk = cache::DiskCache::new(&dir);
    let codec = Codec::of::<Number>();
    disk.store(5, &StageValue::new(Number(2.0)), &codec).unwrap();
    let path = disk.path_for(5);
    // A valid header followed by 5 GB (sparse: it takes no disk space).
    let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    file.set_len(5 << 30).unwrap();
    drop(file);
    // The size check comes before the payload is read (which would need 5 GB of memory).
    match disk.load(5, &codec) {
        cache::DiskLookup::Corrupt(why) => assert!(why.contains("bytes but its header declares"), "{why}"),
        _ => panic!("a 5 GB entry was accepted"),
    }
    assert!(!path.exists(), "the bad entry is removed");
}

#[test]
fn disk_entries_of_another_type_or_encoding_are_recomputed_not_misread() {
    let dir = temp_dir("encoding");
    let disk = cache::DiskCache::new(&dir);
    disk.store(7, &StageValue::new(Number(3.0)), &Codec::of::<Number>()).unwrap();
    // The same bytes would decode as garbage under the new layout; the header says why not.
    match disk.load(7, &Codec::of::<NumberV2>()) {
        cache::DiskLookup::Corrupt(why) => {
            assert!(why.contains("number (encoding 1), expected number (encoding 2)"), "{why}")
        }
        _ => panic!("an entry with an older encoding was trusted"),
    }
    assert!(matches!(disk.load(7, &Codec::of::<Number>()), cache::DiskLookup::Miss), "the stale entry is removed");
    disk.store(8, &StageValue::new(Number(3.0)), &Codec::of::<Number>()).unwrap();
    match disk.load(8, &Codec::of::<crate::transport::ShTransport>()) {
        cache::DiskLookup::Corrupt(why) => assert!(why.contains("expected SH transport"), "{why}"),
        _ => panic!("an entry of another type was trusted"),
    }
}

/// A corrupt memoised part (here every disk entry is damaged) is reported by the stage that
/// reads it, recomputed, and written again.
#[test]
fn corrupt_memo_entries_are_reported_and_replaced() {
    let dir = temp_dir("memo-corrupt");
    let config = || EngineConfig { memory_budget_bytes: 1 << 30, disk_cache: Some(dir.clone()), ..Default::default() };
    let graph = small_default_graph();
    let request = Request::new("objects", vec![StageRef::new("scene", "transport_objects")]);
    let run = || Engine::new(config()).evaluate_request(&graph, &request, &CancelToken::default(), None, &|_, _| {});
    assert!(run().report.failed().is_empty());
    let entries: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .flat_map(|shard| std::fs::read_dir(shard.path()).unwrap().flatten().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "bin"))
        .collect();
    assert!(entries.len() >= 2, "the stage and its parts are on disk: {entries:?}");
    for path in &entries {
        let mut bytes = std::fs::read(path).unwrap();
        let last = bytes.len() - 1;
        bytes[last] ^= 0xff;
        std::fs::write(path, bytes).unwrap();
    }
    let eval = run();
    let stage = eval.report.stages.iter().find(|s| s.stage == "transport_objects").unwrap();
    assert!(
        stage.warnings.iter().any(|w| w.contains("disk cache entry of a part was bad") && w.contains("checksum")),
        "{:?}",
        stage.warnings
    );
    // Written again: a third engine reads every part without a warning.
    let eval = run();
    let stage = eval.report.stages.iter().find(|s| s.stage == "transport_objects").unwrap();
    assert!(stage.warnings.is_empty(), "{:?}", stage.warnings);
}
