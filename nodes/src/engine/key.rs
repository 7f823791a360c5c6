//! Stage keys: 128-bit content hashes of exactly what a stage reads.

use xxhash_rust::xxh3::Xxh3;

/// A stage key. Equal keys mean equal results.
pub type Key = u128;

/// Builds a key from labelled components and remembers each component's own hash, so the
/// engine can say *which* component changed between two evaluations.
pub struct KeyBuilder {
    hasher: Xxh3,
    components: Vec<(String, u64)>,
}

impl KeyBuilder {
    pub fn new(kind: &str, stage: &str, version: u32) -> Self {
        let mut hasher = Xxh3::new();
        hasher.update(kind.as_bytes());
        hasher.update(&[0]);
        hasher.update(stage.as_bytes());
        hasher.update(&version.to_le_bytes());
        Self { hasher, components: Vec::new() }
    }

    /// Adds a labelled component (its bytes must be a canonical encoding).
    pub fn add(&mut self, label: String, bytes: &[u8]) {
        self.hasher.update(&(label.len() as u64).to_le_bytes());
        self.hasher.update(label.as_bytes());
        self.hasher.update(&(bytes.len() as u64).to_le_bytes());
        self.hasher.update(bytes);
        self.components.push((label, xxhash_rust::xxh3::xxh3_64(bytes)));
    }

    pub fn finish(self) -> (Key, Vec<(String, u64)>) {
        (self.hasher.digest128(), self.components)
    }
}

/// Hex form of a key (file names, reports).
pub fn key_hex(key: Key) -> String {
    format!("{key:032x}")
}
