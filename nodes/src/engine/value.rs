//! Open, typed stage values. The engine stores and caches values of any type; each technique
//! owns its value types by implementing [`StageType`] (a name for messages and an approximate
//! size for the memory budget) and, for values that go to the disk cache, [`Persisted`] (a
//! versioned encoding). Stages read their inputs through typed accessors, so a wrong type is
//! an error naming both types.

use super::StageError;
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::any::Any;
use std::fmt;

/// A type a stage can produce.
pub trait StageType: Any + Send + Sync + fmt::Debug {
    /// What the value is, for messages ("SH", "meshes").
    const NAME: &'static str;

    /// Approximate heap size in bytes, for the memory cache's budget.
    fn approx_bytes(&self) -> usize {
        std::mem::size_of_val(self)
    }

    /// How many of its numbers are NaN, infinite or beyond ±1e30 (the engine warns, naming
    /// the stage that produced them). Numeric types say; others have none.
    fn absurd_numbers(&self) -> usize {
        0
    }
}

/// Counts NaN, infinite and beyond-±1e30 numbers (for [`StageType::absurd_numbers`]).
pub fn count_absurd(numbers: impl Iterator<Item = f64>) -> usize {
    numbers.filter(|x| x.is_nan() || x.abs() > 1e30).count()
}

/// A stage type with an encoding for the disk cache. `ENCODING` is bumped whenever the
/// serialised layout changes, so older cache entries are recomputed instead of misread.
pub trait Persisted: StageType + Serialize + DeserializeOwned {
    const ENCODING: u32;
}

/// The object-safe face of [`StageType`].
trait Erased: Any + Send + Sync + fmt::Debug {
    fn type_name(&self) -> &'static str;
    fn approx_bytes(&self) -> usize;
    fn absurd_numbers(&self) -> usize;
    fn as_any(&self) -> &dyn Any;
}

impl<T: StageType> Erased for T {
    fn type_name(&self) -> &'static str {
        T::NAME
    }

    fn approx_bytes(&self) -> usize {
        StageType::approx_bytes(self)
    }

    fn absurd_numbers(&self) -> usize {
        StageType::absurd_numbers(self)
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// The result of a stage: a value of some [`StageType`].
pub struct StageValue(Box<dyn Erased>);

impl StageValue {
    pub fn new<T: StageType>(value: T) -> Self {
        Self(Box::new(value))
    }

    /// The value as a `T`, if it is one.
    pub fn get<T: StageType>(&self) -> Option<&T> {
        self.0.as_any().downcast_ref::<T>()
    }

    /// The value as a `T`, or an error naming what it is instead.
    pub fn expect<T: StageType>(&self) -> Result<&T, StageError> {
        self.get::<T>().ok_or_else(|| StageError::Internal(format!("expected {}, found {}", T::NAME, self.type_name())))
    }

    pub fn type_name(&self) -> &'static str {
        self.0.type_name()
    }

    /// Approximate heap size, for the memory budget.
    pub fn approx_bytes(&self) -> usize {
        64 + self.0.approx_bytes()
    }

    /// NaN, infinite and beyond-±1e30 numbers in the value.
    pub fn absurd_numbers(&self) -> usize {
        self.0.absurd_numbers()
    }
}

impl fmt::Debug for StageValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&self.0, f)
    }
}

/// How a persisted stage's values are written to and read from the disk cache: the type's
/// name and encoding version are stored with each entry and checked on load.
#[derive(Clone, Copy)]
pub struct Codec {
    pub type_name: &'static str,
    pub encoding: u32,
    pub encode: fn(&StageValue) -> Result<Vec<u8>, String>,
    pub decode: fn(&[u8]) -> Result<StageValue, String>,
}

impl fmt::Debug for Codec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Codec({} v{})", self.type_name, self.encoding)
    }
}

impl Codec {
    /// The codec of a persisted type (postcard, versioned by `T::ENCODING`).
    pub const fn of<T: Persisted>() -> Self {
        Self {
            type_name: T::NAME,
            encoding: T::ENCODING,
            encode: |value| {
                let v = value.get::<T>().ok_or_else(|| format!("expected {}, found {}", T::NAME, value.type_name()))?;
                postcard::to_stdvec(v).map_err(|e| e.to_string())
            },
            decode: |bytes| postcard::from_bytes::<T>(bytes).map(StageValue::new).map_err(|e| e.to_string()),
        }
    }
}

/// Implements [`StageType`] (and, with `encoding = N`, [`Persisted`]) for a technique's type,
/// with its approximate size and, with `numbers = |v| …`, an iterator over its `f64` numbers
/// for the engine's check of absurd values:
/// `stage_type!(ShRgb, "SH", encoding = 1, |v| v.coeffs.len() * 24, numbers = |v| v.coeffs.iter().flatten().copied());`
#[macro_export]
macro_rules! stage_type {
    ($ty:ty, $name:literal $(, encoding = $enc:literal)? $(, |$v:ident| $bytes:expr)?
        $(, numbers = |$n:ident| $numbers:expr)? $(,)?) => {
        impl $crate::engine::StageType for $ty {
            const NAME: &'static str = $name;
            $(fn approx_bytes(&self) -> usize {
                let $v = self;
                $bytes
            })?
            $(fn absurd_numbers(&self) -> usize {
                let $n = self;
                $crate::engine::value::count_absurd($numbers)
            })?
        }
        $(impl $crate::engine::Persisted for $ty {
            const ENCODING: u32 = $enc;
        })?
    };
}
