//! Stage keys: 128-bit content hashes of exactly what a stage reads.

/// A stage key. Equal keys mean equal results.
pub type Key = u128;

/// What a key component is: a parameter, an own stage or an upstream stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Component {
    Param(&'static str),
    Stage(&'static str),
    Input(&'static str, &'static str),
}

impl std::fmt::Display for Component {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Component::Param(p) => write!(f, "parameter `{p}`"),
            Component::Stage(s) => write!(f, "stage `{s}`"),
            Component::Input(port, stage) => write!(f, "input `{port}.{stage}`"),
        }
    }
}

/// Builds a key from labelled components and remembers each component's own hash, so the
/// engine can say *which* component changed between two evaluations.
pub struct KeyBuilder {
    bytes: Vec<u8>,
    components: Vec<(Component, u64)>,
}

impl KeyBuilder {
    pub fn new(kind: &str, stage: &str, version: u32) -> Self {
        let mut bytes = Vec::with_capacity(256);
        bytes.extend_from_slice(kind.as_bytes());
        bytes.push(0);
        bytes.extend_from_slice(stage.as_bytes());
        bytes.extend_from_slice(&version.to_le_bytes());
        Self { bytes, components: Vec::with_capacity(8) }
    }

    /// Adds a labelled component (its bytes must be a canonical encoding).
    pub fn add(&mut self, label: Component, bytes: &[u8]) {
        let name = match label {
            Component::Param(p) => p,
            Component::Stage(s) => s,
            Component::Input(port, _) => port,
        };
        self.bytes.extend_from_slice(&[match label {
            Component::Param(_) => 0,
            Component::Stage(_) => 1,
            Component::Input(..) => 2,
        }]);
        self.bytes.extend_from_slice(&(name.len() as u64).to_le_bytes());
        self.bytes.extend_from_slice(name.as_bytes());
        if let Component::Input(_, stage) = label {
            self.bytes.extend_from_slice(stage.as_bytes());
        }
        self.bytes.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        self.bytes.extend_from_slice(bytes);
        self.components.push((label, xxhash_rust::xxh3::xxh3_64(bytes)));
    }

    pub fn finish(self) -> (Key, Vec<(Component, u64)>) {
        (xxhash_rust::xxh3::xxh3_128(&self.bytes), self.components)
    }
}

/// Hex form of a key (file names, reports).
pub fn key_hex(key: Key) -> String {
    format!("{key:032x}")
}

/// Serde helpers writing keys as 32 hex digits.
pub mod hex {
    use super::Key;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(key: &Key, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&super::key_hex(*key))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Key, D::Error> {
        let text = String::deserialize(d)?;
        Key::from_str_radix(&text, 16).map_err(serde::de::Error::custom)
    }
}
