//! Result caches: a bounded in-memory LRU cache and a checksummed, content-addressed disk
//! cache for expensive stages.

use super::key::{Key, key_hex};
use super::value::{Codec, StageValue};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// In-memory cache bounded by an approximate byte budget; least recently used entries go
/// first (the `lru` crate keeps the order, so eviction is O(1) per entry).
pub struct MemoryCache {
    budget: usize,
    used: usize,
    entries: lru::LruCache<Key, (Arc<StageValue>, usize)>,
}

impl MemoryCache {
    pub fn new(budget_bytes: usize) -> Self {
        Self { budget: budget_bytes, used: 0, entries: lru::LruCache::unbounded() }
    }

    pub fn get(&mut self, key: Key) -> Option<Arc<StageValue>> {
        self.entries.get(&key).map(|e| e.0.clone())
    }

    pub fn contains(&self, key: Key) -> bool {
        self.entries.contains(&key)
    }

    pub fn insert(&mut self, key: Key, value: Arc<StageValue>) {
        let size = value.approx_bytes();
        if let Some((_, old)) = self.entries.put(key, (value, size)) {
            self.used -= old;
        }
        self.used += size;
        // The entry just inserted is the most recent, so it goes last (and stays when alone).
        while self.used > self.budget && self.entries.len() > 1 {
            match self.entries.pop_lru() {
                Some((_, (_, removed))) => self.used -= removed,
                None => break,
            }
        }
    }

    pub fn used_bytes(&self) -> usize {
        self.used
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

/// Version 2 records the value's type name and encoding version in every entry.
const MAGIC: &[u8; 8] = b"LLCACHE2";

/// What a disk lookup found.
pub enum DiskLookup {
    Hit(StageValue),
    Miss,
    /// An entry existed but failed its checks (or holds another type or encoding version);
    /// it was removed and must be recomputed.
    Corrupt(String),
}

/// Content-addressed files `dir/ab/<key>.bin`: magic, key, the value's type name and encoding
/// version, payload length, xxh3-64 checksum, payload. Writes are atomic (temporary file +
/// rename). Bounded by a byte budget: a hit marks its entry used (its modification time), and
/// [`Self::prune`] removes the least recently used entries beyond the budget. It runs when the
/// cache opens and again after every eighth of the budget written.
#[derive(Clone, Debug)]
pub struct DiskCache {
    dir: PathBuf,
    budget_bytes: u64,
    /// Bytes written since the last prune (shared by clones).
    written: Arc<AtomicU64>,
}

/// What [`DiskCache::prune`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PruneReport {
    pub kept_bytes: u64,
    pub removed_entries: usize,
    pub removed_bytes: u64,
}

/// Disk cache budget unless configured: 8 GiB.
pub const DEFAULT_DISK_BUDGET_BYTES: u64 = 8 << 30;

impl DiskCache {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self::with_budget(dir, DEFAULT_DISK_BUDGET_BYTES)
    }

    /// A cache in `dir` kept under `budget_bytes` (pruned now).
    pub fn with_budget(dir: impl Into<PathBuf>, budget_bytes: u64) -> Self {
        let cache = Self { dir: dir.into(), budget_bytes, written: Arc::new(AtomicU64::new(0)) };
        let _ = cache.prune();
        cache
    }

    /// Removes the least recently used entries until the rest fit the budget.
    pub fn prune(&self) -> std::io::Result<PruneReport> {
        self.written.store(0, Ordering::Relaxed);
        let mut entries = Vec::new();
        let Ok(shards) = std::fs::read_dir(&self.dir) else { return Ok(PruneReport::default()) };
        for shard in shards.flatten() {
            let Ok(files) = std::fs::read_dir(shard.path()) else { continue };
            for file in files.flatten() {
                let path = file.path();
                if path.extension().is_none_or(|e| e != "bin") {
                    // A write killed before its rename leaves `.tmpXXXXXX`: gone after an hour.
                    let stale = file.metadata().and_then(|m| m.modified()).ok().and_then(|t| t.elapsed().ok());
                    if file.file_name().to_string_lossy().starts_with(".tmp")
                        && stale.is_some_and(|age| age.as_secs() > 3600)
                    {
                        let _ = std::fs::remove_file(&path);
                    }
                    continue;
                }
                if let Ok(meta) = file.metadata() {
                    let used = meta.modified().unwrap_or(std::time::UNIX_EPOCH);
                    entries.push((used, meta.len(), path));
                }
            }
        }
        let mut report = PruneReport { kept_bytes: entries.iter().map(|e| e.1).sum(), ..Default::default() };
        entries.sort();
        for (_, size, path) in entries {
            if report.kept_bytes <= self.budget_bytes {
                break;
            }
            if std::fs::remove_file(&path).is_ok() {
                report.kept_bytes -= size;
                report.removed_bytes += size;
                report.removed_entries += 1;
            }
        }
        Ok(report)
    }

    /// `$XDG_CACHE_HOME/lightloom`, else `~/.cache/lightloom`, else a temporary directory.
    pub fn default_dir() -> PathBuf {
        if let Some(dir) = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
            return PathBuf::from(dir).join("lightloom");
        }
        if let Some(home) = std::env::var_os("HOME").filter(|d| !d.is_empty()) {
            return PathBuf::from(home).join(".cache").join("lightloom");
        }
        std::env::temp_dir().join("lightloom-cache")
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn path_for(&self, key: Key) -> PathBuf {
        let hex = key_hex(key);
        self.dir.join(&hex[..2]).join(format!("{hex}.bin"))
    }

    /// The entry for `key`, decoded with `codec` (whose type and encoding it must record).
    pub fn load(&self, key: Key, codec: &Codec) -> DiskLookup {
        let path = self.path_for(key);
        // Only regular files: opening a FIFO would block.
        if !std::fs::metadata(&path).is_ok_and(|m| m.is_file()) {
            return DiskLookup::Miss;
        }
        let Ok(mut file) = std::fs::File::open(&path) else { return DiskLookup::Miss };
        let read = read_entry(&mut file, key, codec);
        drop(file);
        match read {
            Ok(value) => {
                // Mark it used, so pruning removes it last.
                if let Ok(file) = std::fs::OpenOptions::new().append(true).open(&path) {
                    let _ = file.set_modified(std::time::SystemTime::now());
                }
                DiskLookup::Hit(value)
            }
            Err(why) => {
                let _ = std::fs::remove_file(&path);
                DiskLookup::Corrupt(format!("{}: {why}", path.display()))
            }
        }
    }

    pub fn store(&self, key: Key, value: &StageValue, codec: &Codec) -> std::io::Result<()> {
        let payload = (codec.encode)(value).map_err(std::io::Error::other)?;
        let path = self.path_for(key);
        let dir = path.parent().expect("entries live in a subfolder");
        std::fs::create_dir_all(dir)?;
        let mut file = tempfile::NamedTempFile::new_in(dir)?;
        file.write_all(MAGIC)?;
        file.write_all(&key.to_le_bytes())?;
        let name = codec.type_name.as_bytes();
        file.write_all(&[name.len().min(255) as u8])?;
        file.write_all(&name[..name.len().min(255)])?;
        file.write_all(&codec.encoding.to_le_bytes())?;
        file.write_all(&(payload.len() as u64).to_le_bytes())?;
        file.write_all(&xxhash_rust::xxh3::xxh3_64(&payload).to_le_bytes())?;
        file.write_all(&payload)?;
        file.as_file().sync_all()?;
        file.persist(&path).map_err(|e| e.error)?;
        let entry_bytes = payload.len() as u64 + 64;
        if self.written.fetch_add(entry_bytes, Ordering::Relaxed) + entry_bytes > self.budget_bytes / 8 {
            self.prune()?;
        }
        Ok(())
    }
}

/// Reads fixed-size fields off the front of an entry.
struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.0.len() < n {
            return Err("truncated header".into());
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Ok(head)
    }

    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
}

/// The longest header: magic, key, name length and name, encoding, length, checksum.
const MAX_HEADER_BYTES: u64 = 8 + 16 + 1 + 255 + 4 + 8 + 8;

/// Reads and checks one entry. The header is read first and its declared payload length must
/// match the file's size, so a huge or foreign file is rejected without being read whole.
fn read_entry(file: &mut std::fs::File, key: Key, codec: &Codec) -> Result<StageValue, String> {
    use std::io::Read;
    let size = file.metadata().map_err(|e| e.to_string())?.len();
    let mut bytes = Vec::new();
    (&mut *file).take(MAX_HEADER_BYTES).read_to_end(&mut bytes).map_err(|e| e.to_string())?;
    let mut r = Reader(&bytes);
    if r.take(8).ok() != Some(MAGIC.as_slice()) {
        return Err("not a Lightloom cache entry (or an older cache format)".into());
    }
    let stored_key = u128::from_le_bytes(r.take(16)?.try_into().unwrap());
    if stored_key != key {
        return Err("entry holds a different key".into());
    }
    let name_len = r.take(1)?[0] as usize;
    let name = String::from_utf8_lossy(r.take(name_len)?).to_string();
    let encoding = u32::from_le_bytes(r.take(4)?.try_into().unwrap());
    if name != codec.type_name || encoding != codec.encoding {
        return Err(format!(
            "entry holds {name} (encoding {encoding}), expected {} (encoding {})",
            codec.type_name, codec.encoding
        ));
    }
    let len = r.u64()?;
    let checksum = r.u64()?;
    let header = (bytes.len() - r.0.len()) as u64;
    if header.checked_add(len) != Some(size) {
        return Err(format!("the file is {size} bytes but its header declares {}", header.saturating_add(len)));
    }
    file.read_to_end(&mut bytes).map_err(|e| e.to_string())?;
    let payload = &bytes[header as usize..];
    if payload.len() as u64 != len {
        return Err(format!("truncated: {} of {len} payload bytes", payload.len()));
    }
    if xxhash_rust::xxh3::xxh3_64(payload) != checksum {
        return Err("checksum mismatch".into());
    }
    (codec.decode)(payload).map_err(|e| format!("undecodable payload: {e}"))
}
