//! Each relighting mode as one value ([`ModeFrame`]): what a frame of it requests beyond the
//! stages every mode reads, what it reads of each linked material, and how it gathers its
//! surfaces. [`mode_stages`](super::mode_stages), the frame request and the gather ask the
//! mode's value and branch on no mode; each value sits beside its surfaces (`prt.rs`,
//! `wavelet.rs`, `rsl.rs`), so a new mode is its surfaces, its value and one line in [`of`].

use super::gather::{Gather, MaterialParts};
use super::*;

/// The Output's mode and view (its parameters parsed once) and the nodes linked to it that the
/// modes read, and whether its environment's sun is lit apart from the transport.
pub(super) struct Linked<'a> {
    pub output: &'a str,
    pub mode: Mode,
    pub view: View,
    pub scene: Option<String>,
    pub environment: Option<String>,
    pub square_lights: Option<String>,
    pub separate_sun: bool,
}

impl<'a> Linked<'a> {
    pub fn new(graph: &Graph, output: &'a str) -> Self {
        let upstream = |port: &str| graph.upstream(output, port).map(|n| n.id.clone());
        let (mode, view) = graph.node(output).map_or((Mode::ShIrradiance, View::Approximation), output_mode_and_view);
        Self {
            output,
            mode,
            view,
            scene: upstream("scene"),
            environment: upstream("environment"),
            square_lights: upstream("square_lights"),
            separate_sun: separates_sun(graph, output, mode),
        }
    }
}

/// What every mode's surfaces are made from besides its own stages: the SH light its transport
/// carries, the environment through fog, the geometry.
pub(super) struct SurfaceInputs<'a> {
    pub light: Option<&'a ShRgb>,
    pub fogged: Option<&'a FoggedEnvironment>,
    pub geometry: &'a Geometry,
}

/// One relighting mode's part of a frame.
pub(super) trait ModeFrame: Sync {
    /// The stages of each linked material it reads ([`MaterialParts::mode_stages`]).
    fn material_stages(&self) -> &'static [&'static str] {
        &[]
    }

    /// Whether it cannot draw with the default material (no material linked).
    fn needs_material(&self) -> bool {
        false
    }

    /// What it requests beyond the stages every mode reads.
    fn stages(&self, linked: &Linked) -> Vec<StageRef>;

    /// What it requests to be relit by the engine for a viewport that relights on the CPU.
    fn cpu_relight_stages(&self, _linked: &Linked) -> Vec<StageRef> {
        Vec::new()
    }

    /// Its surfaces, from the evaluation its request was evaluated in.
    fn surfaces(&self, g: &Gather, parts: &MaterialParts, inputs: &SurfaceInputs) -> Result<Surfaces, String>;
}

/// The part of a frame of `mode`.
pub(super) fn of(mode: Mode) -> &'static dyn ModeFrame {
    match mode {
        Mode::ShIrradiance => &prt::Irradiance,
        Mode::ShPrt => &prt::Prt { adaptive: false },
        Mode::ShAdaptive => &prt::Prt { adaptive: true },
        Mode::WaveletVertex => &wavelet::Wavelet { texels: false },
        Mode::WaveletPixel => &wavelet::Wavelet { texels: true },
        Mode::Rsl => &rsl::Rsl,
    }
}
