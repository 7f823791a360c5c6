//! Lightloom's coefficient math, graph model and evaluation engine.
//! No GPU and no UI code lives here, so everything is testable headless.
//!
//! The math core, used by every lighting technique:
//! - [`sh`]: real orthonormal spherical harmonics (evaluation, projection, rotation,
//!   zonal harmonics, convolution, windows, Gaunt products).
//! - [`cubemap`]: cube-map and equirectangular parameterisations and resampling.
//! - [`wavelet`]: Haar wavelets on cube faces and on the subdivided icosahedron, sparse
//!   nonlinear approximation and triple product integrals.
//! - [`sat`]: summed-area tables.

pub mod adaptive_sh;
pub mod bake;
pub mod brdf;
pub mod choice;
pub mod cubemap;
pub mod engine;
pub mod envmap_io;
pub mod frame;
#[doc(hidden)]
pub mod fuzzing;
pub mod gltf_import;
pub mod ies;
pub mod kinds;
pub mod light;
pub mod light_texture;
pub mod lightmap;
pub mod limits;
pub mod mesh;
pub mod near_field;
pub mod normal_filtering;
pub mod paint;
pub mod picture;
pub mod preview;
pub mod probes;
pub mod project;
pub mod prt;
pub mod quadrature;
pub mod raycast;
pub mod reference;
pub mod reflected_lobe;
pub mod rsl;
pub mod sampling;
pub mod sat;
pub mod scene_object;
pub mod sh;
pub mod sh_exponential;
pub mod single_scattering;
pub mod sky;
pub mod specular_cube;
pub mod sphere_set;
pub mod sun;
pub mod transport;
pub mod triple_product;
pub mod wavelet;
