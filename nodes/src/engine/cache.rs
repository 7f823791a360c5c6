//! Result caches: a bounded in-memory LRU cache and a checksummed, content-addressed disk
//! cache for expensive stages.

use super::StageValue;
use super::key::{Key, key_hex};
use rustc_hash::FxHashMap as HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// In-memory cache bounded by an approximate byte budget; least recently used entries go first.
pub struct MemoryCache {
    budget: usize,
    used: usize,
    tick: u64,
    entries: HashMap<Key, (Arc<StageValue>, usize, u64)>,
}

impl MemoryCache {
    pub fn new(budget_bytes: usize) -> Self {
        Self { budget: budget_bytes, used: 0, tick: 0, entries: HashMap::default() }
    }

    pub fn get(&mut self, key: Key) -> Option<Arc<StageValue>> {
        self.tick += 1;
        let tick = self.tick;
        self.entries.get_mut(&key).map(|e| {
            e.2 = tick;
            e.0.clone()
        })
    }

    pub fn contains(&self, key: Key) -> bool {
        self.entries.contains_key(&key)
    }

    pub fn insert(&mut self, key: Key, value: Arc<StageValue>) {
        self.tick += 1;
        let size = value.approx_bytes();
        if let Some(old) = self.entries.insert(key, (value, size, self.tick)) {
            self.used -= old.1;
        }
        self.used += size;
        while self.used > self.budget && self.entries.len() > 1 {
            let oldest = self.entries.iter().filter(|(k, _)| **k != key).min_by_key(|(_, e)| e.2).map(|(k, _)| *k);
            match oldest {
                Some(k) => {
                    let removed = self.entries.remove(&k).unwrap();
                    self.used -= removed.1;
                }
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

const MAGIC: &[u8; 8] = b"LLCACHE1";

/// What a disk lookup found.
pub enum DiskLookup {
    Hit(StageValue),
    Miss,
    /// An entry existed but failed its checks; it was removed and must be recomputed.
    Corrupt(String),
}

/// Content-addressed files `dir/ab/<key>.bin`: magic, key, payload length, xxh3-64 checksum,
/// postcard payload. Writes are atomic (temporary file + rename).
#[derive(Clone, Debug)]
pub struct DiskCache {
    dir: PathBuf,
}

impl DiskCache {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
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

    pub fn load(&self, key: Key) -> DiskLookup {
        let path = self.path_for(key);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(_) => return DiskLookup::Miss,
        };
        match decode(&bytes, key) {
            Ok(value) => DiskLookup::Hit(value),
            Err(why) => {
                let _ = std::fs::remove_file(&path);
                DiskLookup::Corrupt(format!("{}: {why}", path.display()))
            }
        }
    }

    pub fn store(&self, key: Key, value: &StageValue) -> std::io::Result<()> {
        let payload = postcard::to_stdvec(value).map_err(std::io::Error::other)?;
        let path = self.path_for(key);
        std::fs::create_dir_all(path.parent().unwrap())?;
        let tmp = path.with_extension(format!("tmp{}", std::process::id()));
        {
            let mut file = std::fs::File::create(&tmp)?;
            file.write_all(MAGIC)?;
            file.write_all(&key.to_le_bytes())?;
            file.write_all(&(payload.len() as u64).to_le_bytes())?;
            file.write_all(&xxhash_rust::xxh3::xxh3_64(&payload).to_le_bytes())?;
            file.write_all(&payload)?;
            file.sync_all()?;
        }
        std::fs::rename(&tmp, &path)
    }
}

fn decode(bytes: &[u8], key: Key) -> Result<StageValue, String> {
    let header = 8 + 16 + 8 + 8;
    if bytes.len() < header || &bytes[..8] != MAGIC {
        return Err("not a Lightloom cache entry".into());
    }
    let stored_key = u128::from_le_bytes(bytes[8..24].try_into().unwrap());
    if stored_key != key {
        return Err("entry holds a different key".into());
    }
    let len = u64::from_le_bytes(bytes[24..32].try_into().unwrap()) as usize;
    let checksum = u64::from_le_bytes(bytes[32..40].try_into().unwrap());
    let payload = &bytes[header..];
    if payload.len() != len {
        return Err(format!("truncated: {} of {len} payload bytes", payload.len()));
    }
    if xxhash_rust::xxh3::xxh3_64(payload) != checksum {
        return Err("checksum mismatch".into());
    }
    postcard::from_bytes(payload).map_err(|e| format!("undecodable payload: {e}"))
}
