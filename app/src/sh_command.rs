//! `lightloom sh`: SH ambient lighting for game engines.

use anyhow::{Result, bail};
use clap::Args;
use glam::DVec3;
use lightloom_nodes::cubemap::Equirect;
use lightloom_nodes::envmap_io::load_equirect;
use lightloom_nodes::sh::{self, ShBasis, ShRgb, Window};
use lightloom_nodes::sky::ProceduralSky;
use serde::Serialize;
use std::path::PathBuf;

#[derive(Args, Clone, Debug)]
pub struct ShArgs {
    /// Equirectangular environment map (.exr or .hdr). Omit with --builtin-sky.
    pub envmap: Option<PathBuf>,
    /// Use the built-in procedural sky instead of a file.
    #[arg(long, conflicts_with = "envmap")]
    pub builtin_sky: bool,
    /// Number of SH bands (band l = 0..N-1, N² coefficients).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=32))]
    pub bands: u32,
    /// Ringing window applied to the coefficients: none, hanning, lanczos.
    #[arg(long, default_value = "none")]
    pub window: String,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Report {
    source: String,
    width: usize,
    height: usize,
    bands: usize,
    window: String,
    convention: &'static str,
    coefficients: Vec<Coefficient>,
    irradiance: Vec<AxisIrradiance>,
    warnings: Vec<String>,
}

#[derive(Serialize)]
struct Coefficient {
    l: usize,
    m: i64,
    rgb: [f64; 3],
}

#[derive(Serialize)]
struct AxisIrradiance {
    axis: &'static str,
    direction: [f64; 3],
    rgb: [f64; 3],
}

const CONVENTION: &str = "real orthonormal SH, index l*(l+1)+m, no Condon-Shortley phase: \
Y00=0.282095, Y1-1=0.488603*y, Y10=0.488603*z, Y11=0.488603*x (world +Y up, right-handed); \
coefficients are radiance L_lm = integral of L*Y_lm over the sphere; irradiance E(n) = sum A_l L_lm Y_lm(n)";

pub fn run(args: &ShArgs) -> Result<()> {
    let bands = args.bands as usize;
    let window = match args.window.as_str() {
        "none" => Window::None,
        "hanning" => Window::Hanning { width: bands as f64 + 1.0 },
        "lanczos" => Window::Lanczos { width: bands as f64 + 1.0 },
        other => bail!("unknown window `{other}`: use none, hanning or lanczos"),
    };
    let (source, image, warnings) = match (&args.envmap, args.builtin_sky) {
        (Some(path), _) => {
            let loaded = load_equirect(path)?;
            (path.display().to_string(), loaded.image, loaded.warnings)
        }
        (None, true) => {
            let sky = ProceduralSky::default();
            ("built-in procedural sky".to_string(), Equirect::from_fn(512, 256, 3, |d| sky.radiance(d)), Vec::new())
        }
        (None, false) => bail!("give an environment map (.exr or .hdr) or --builtin-sky"),
    };
    let radiance = sh::project_equirect(&image, bands).scale_bands(&window.factors(bands));
    let report = build_report(source, &image, &radiance, &args.window, warnings);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&report);
    }
    Ok(())
}

fn build_report(source: String, image: &Equirect, radiance: &ShRgb, window: &str, warnings: Vec<String>) -> Report {
    let bands = radiance.bands;
    let coefficients = (0..bands)
        .flat_map(|l| (-(l as i64)..=l as i64).map(move |m| (l, m)))
        .map(|(l, m)| Coefficient { l, m, rgb: radiance.coeffs[sh::index(l, m)] })
        .collect();
    let irradiance_sh = radiance.irradiance();
    let basis = ShBasis::new(bands);
    let axes =
        [("+X", DVec3::X), ("-X", -DVec3::X), ("+Y", DVec3::Y), ("-Y", -DVec3::Y), ("+Z", DVec3::Z), ("-Z", -DVec3::Z)];
    let irradiance = axes
        .iter()
        .map(|(axis, d)| AxisIrradiance { axis, direction: d.to_array(), rgb: irradiance_sh.eval(&basis, *d) })
        .collect();
    Report {
        source,
        width: image.width,
        height: image.height,
        bands,
        window: window.to_string(),
        convention: CONVENTION,
        coefficients,
        irradiance,
        warnings,
    }
}

fn print_text(report: &Report) {
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "{} ({}x{}), {} bands, window {}",
        report.source, report.width, report.height, report.bands, report.window
    );
    println!("convention: {}", report.convention);
    println!("\nSH radiance coefficients (R G B):");
    for c in &report.coefficients {
        println!("  l={:<2} m={:>3}  {:>12.6} {:>12.6} {:>12.6}", c.l, c.m, c.rgb[0], c.rgb[1], c.rgb[2]);
    }
    println!("\nIrradiance E(n) (R G B):");
    for a in &report.irradiance {
        println!("  {}  {:>12.6} {:>12.6} {:>12.6}", a.axis, a.rgb[0], a.rgb[1], a.rgb[2]);
    }
}
