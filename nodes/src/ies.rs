//! IES LM-63 photometric files (LM-63-1986, -1991, -1995, -2002 and -2019): the candela
//! distribution fixture makers publish, read with the bad-input checks every loader here has,
//! and evaluated as the intensity in any direction.
//!
//! Only type C photometry is read (the goniometer of nearly every architectural luminaire):
//! vertical angles `γ` from the nadir (0°, the luminaire's axis, pointing down) to the zenith
//! (180°), horizontal angles `C` about that axis from the luminaire's length (0°) towards its
//! width (90°). Horizontal angles ending at 0°, 90° or 180° mean the file stores one plane,
//! one quadrant or one half of an axially, quadrilaterally or bilaterally symmetric
//! distribution; 90°–270° is bilateral about the 90°–270° plane. Between listed angles the
//! intensity is interpolated linearly in `γ` and in `C`; beyond the last vertical angle it is
//! 0 (a downlight's file stops at 90°). `TILT` data (how output varies as the lamp tilts) is
//! skipped: it matters only for a luminaire mounted tilted.

use std::f64::consts::PI;

/// Angles per axis a file may list (real files list at most a few hundred).
pub const MAX_ANGLES: usize = 4096;
/// Candela values a file may hold.
pub const MAX_VALUES: usize = 1 << 20;
/// Bytes of a file read.
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// Largest candela value read (a searchlight peaks near 1e8 cd).
pub const MAX_CANDELA: f64 = 1e9;

/// Lumens of a watt at 555 nm: a candela is `1/683` W/sr of green light.
pub const LUMENS_PER_WATT: f64 = 683.0;

/// A type C candela distribution.
#[derive(Clone, Debug, PartialEq)]
pub struct Photometry {
    /// Vertical angles `γ`, degrees, ascending, within `[0, 180]`.
    pub vertical: Vec<f64>,
    /// Horizontal angles `C`, degrees, ascending.
    pub horizontal: Vec<f64>,
    /// Candela per horizontal angle, each a row over the vertical angles, with the file's
    /// multiplier and ballast factor applied.
    pub candela: Vec<Vec<f64>>,
    /// The file's keywords (`[MANUFAC]`, `[LUMINAIRE]`, …) as `(keyword, text)`.
    pub keywords: Vec<(String, String)>,
}

/// Why a file is not a usable LM-63 type C distribution.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct IesError(String);

fn bad(message: impl Into<String>) -> IesError {
    IesError(message.into())
}

impl Photometry {
    /// Reads an `.ies` file, at most [`MAX_FILE_BYTES`].
    pub fn load(path: &std::path::Path) -> Result<Self, IesError> {
        let bytes = crate::limits::read_regular_file(path, MAX_FILE_BYTES).map_err(IesError)?;
        Self::parse(&bytes).map_err(|e| bad(format!("{}: {e}", path.display())))
    }

    /// Parses an LM-63 file's bytes (any encoding of its header text; numbers are ASCII).
    pub fn parse(bytes: &[u8]) -> Result<Self, IesError> {
        let text = String::from_utf8_lossy(bytes);
        let mut lines = text.lines();
        let mut keywords = Vec::new();
        let mut tilt = None;
        for line in lines.by_ref() {
            let line = line.trim();
            if let Some(rest) = line.strip_prefix("TILT=").or_else(|| line.strip_prefix("TILT =")) {
                tilt = Some(rest.trim().to_owned());
                break;
            }
            if let Some(rest) = line.strip_prefix('[')
                && let Some((keyword, value)) = rest.split_once(']')
            {
                keywords.push((keyword.to_owned(), value.trim().to_owned()));
            }
        }
        let tilt = tilt.ok_or_else(|| bad("no TILT= line: not an IES LM-63 photometric file"))?;
        let mut numbers =
            lines.flat_map(|l| l.split(|c: char| c.is_whitespace() || c == ',')).filter(|t| !t.is_empty());
        let mut next = |what: &str| -> Result<f64, IesError> {
            let token = numbers.next().ok_or_else(|| bad(format!("the file ends before {what}")))?;
            let value: f64 = token.parse().map_err(|_| bad(format!("{what}: `{token}` is not a number")))?;
            if value.is_finite() { Ok(value) } else { Err(bad(format!("{what} is not finite"))) }
        };
        let count = |value: f64, what: &str, max: usize| -> Result<usize, IesError> {
            if value.fract() != 0.0 || value < 0.0 || value > max as f64 {
                return Err(bad(format!("{what} is {value}; expected a whole number up to {max}")));
            }
            Ok(value as usize)
        };
        if tilt.eq_ignore_ascii_case("INCLUDE") {
            // Lamp-to-luminaire geometry, then the tilt angles and their factors: skipped.
            next("the tilt geometry")?;
            let pairs = count(next("the number of tilt angles")?, "the number of tilt angles", MAX_ANGLES)?;
            for _ in 0..2 * pairs {
                next("the tilt table")?;
            }
        }
        let _lamps = next("the number of lamps")?;
        let _lumens = next("the lumens per lamp")?;
        let multiplier = next("the candela multiplier")?;
        let vertical_count =
            count(next("the number of vertical angles")?, "the number of vertical angles", MAX_ANGLES)?;
        let horizontal_count =
            count(next("the number of horizontal angles")?, "the number of horizontal angles", MAX_ANGLES)?;
        let photometric_type = next("the photometric type")?;
        for what in ["the units type", "the width", "the length", "the height"] {
            next(what)?;
        }
        let ballast = next("the ballast factor")?;
        next("the ballast-lamp photometric factor")?;
        next("the input watts")?;
        match photometric_type as i64 {
            1 => {}
            2 | 3 => {
                return Err(bad(format!(
                    "photometric type {} (type {}: floodlights and vehicle lamps) is not supported; only type C",
                    photometric_type,
                    if photometric_type as i64 == 2 { "B" } else { "A" }
                )));
            }
            _ => return Err(bad(format!("photometric type {photometric_type} is not 1, 2 or 3"))),
        }
        if vertical_count == 0 || horizontal_count == 0 {
            return Err(bad("the file lists no vertical or no horizontal angles"));
        }
        if vertical_count * horizontal_count > MAX_VALUES {
            return Err(bad(format!(
                "{vertical_count} × {horizontal_count} candela values are more than the {MAX_VALUES} read"
            )));
        }
        if multiplier <= 0.0 || ballast <= 0.0 {
            return Err(bad(format!(
                "the candela multiplier ({multiplier}) and ballast factor ({ballast}) must be positive"
            )));
        }
        let vertical = (0..vertical_count).map(|_| next("the vertical angles")).collect::<Result<Vec<_>, _>>()?;
        let horizontal = (0..horizontal_count).map(|_| next("the horizontal angles")).collect::<Result<Vec<_>, _>>()?;
        let mut candela = Vec::with_capacity(horizontal_count);
        for _ in 0..horizontal_count {
            let row = (0..vertical_count).map(|_| next("the candela values")).collect::<Result<Vec<_>, _>>()?;
            if row.iter().any(|c| *c < 0.0) {
                return Err(bad("a candela value is negative"));
            }
            let row: Vec<f64> = row.into_iter().map(|c| c * multiplier * ballast).collect();
            if row.iter().any(|c| !c.is_finite() || *c > MAX_CANDELA) {
                return Err(bad(format!("a candela value times the multiplier is over {MAX_CANDELA:e}")));
            }
            candela.push(row);
        }
        let ascending = |v: &[f64]| v.windows(2).all(|w| w[0] < w[1]);
        if !ascending(&vertical) || vertical[0] < 0.0 || vertical[vertical_count - 1] > 180.0 {
            return Err(bad("the vertical angles must rise strictly within 0°–180°"));
        }
        let (first, last) = (horizontal[0], horizontal[horizontal_count - 1]);
        if !ascending(&horizontal) || !(first == 0.0 || (first == 90.0 && last == 270.0)) || last > 360.0 {
            return Err(bad(format!(
                "the horizontal angles ({first}°–{last}°) must rise strictly from 0° to at most 360° (or run 90°–270°)"
            )));
        }
        Ok(Self { vertical, horizontal, candela, keywords })
    }

    /// The largest candela value.
    pub fn peak(&self) -> f64 {
        self.candela.iter().flatten().fold(0.0, |m, &c| m.max(c))
    }

    /// Candela at vertical angle `gamma` and horizontal angle `c` (degrees).
    pub fn candela(&self, gamma: f64, c: f64) -> f64 {
        let c = self.fold_horizontal(c);
        let (last_v, v) = (self.vertical.len() - 1, &self.vertical);
        if gamma < v[0] || gamma > v[last_v] {
            return 0.0;
        }
        let row = |r: &[f64]| interpolate(v, r, gamma);
        if self.horizontal.len() == 1 {
            return row(&self.candela[0]);
        }
        let h = &self.horizontal;
        let last_h = h.len() - 1;
        if c >= h[last_h] {
            // A full circle's gap from the last angle back to 360° = 0°.
            if h[0] == 0.0 && h[last_h] < 360.0 {
                let t = (c - h[last_h]) / (360.0 - h[last_h]);
                return row(&self.candela[last_h]) * (1.0 - t) + row(&self.candela[0]) * t;
            }
            return row(&self.candela[last_h]);
        }
        let i = h.partition_point(|&a| a <= c).clamp(1, last_h);
        let t = (c - h[i - 1]) / (h[i] - h[i - 1]);
        row(&self.candela[i - 1]) * (1.0 - t) + row(&self.candela[i]) * t
    }

    /// `c` (degrees, any) brought into the range the file stores, by its symmetry.
    fn fold_horizontal(&self, c: f64) -> f64 {
        let c = c.rem_euclid(360.0);
        let (first, last) = (self.horizontal[0], self.horizontal[self.horizontal.len() - 1]);
        if last == 0.0 {
            0.0
        } else if last == 90.0 {
            let c = if c > 180.0 { 360.0 - c } else { c };
            if c > 90.0 { 180.0 - c } else { c }
        } else if last == 180.0 {
            if c > 180.0 { 360.0 - c } else { c }
        } else if first == 90.0 && last == 270.0 {
            if c < 90.0 {
                180.0 - c
            } else if c > 270.0 {
                540.0 - c
            } else {
                c
            }
        } else {
            c
        }
    }

    /// Luminous flux, lumens: `∫ I dω` over the sphere (midpoint rule on a half-degree grid).
    pub fn lumens(&self) -> f64 {
        let (rows, cols) = (360, 720);
        let (d_theta, d_phi) = (PI / rows as f64, 2.0 * PI / cols as f64);
        let mut sum = 0.0;
        for r in 0..rows {
            let theta = (r as f64 + 0.5) * d_theta;
            let ring: f64 =
                (0..cols).map(|k| self.candela(theta.to_degrees(), ((k as f64 + 0.5) * d_phi).to_degrees())).sum();
            sum += ring * theta.sin() * d_theta * d_phi;
        }
        sum
    }
}

/// Linear interpolation of `values` over ascending `angles` at `x` (inside their range).
fn interpolate(angles: &[f64], values: &[f64], x: f64) -> f64 {
    if angles.len() == 1 {
        return values[0];
    }
    let i = angles.partition_point(|&a| a <= x).clamp(1, angles.len() - 1);
    let t = ((x - angles[i - 1]) / (angles[i] - angles[i - 1])).clamp(0.0, 1.0);
    values[i - 1] * (1.0 - t) + values[i] * t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn asset(name: &str) -> Photometry {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/ies").join(name);
        Photometry::load(&path).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The shipped files read with their own numbers: angles, multiplier, values at listed
    /// angles and between them.
    #[test]
    fn the_shipped_profiles_read_as_their_files_say() {
        let spot = asset("downlight_30.ies");
        assert_eq!((spot.vertical.len(), spot.horizontal.len()), (19, 1));
        assert_eq!(spot.candela(0.0, 0.0), 7399.9);
        assert_eq!(spot.candela(15.0, 123.0), 3707.0);
        assert!((spot.candela(12.5, 0.0) - (6097.7 + 3707.0) / 2.0).abs() < 1e-9);
        assert_eq!(spot.candela(120.0, 0.0), 0.0, "nothing above the last vertical angle");
        let wall = asset("wall_pack.ies");
        assert_eq!((wall.vertical.len(), wall.horizontal.len()), (25, 21));
        // Bilateral symmetry: C and 360° − C read the same row.
        assert_eq!(wall.candela(30.0, 45.0), wall.candela(30.0, 315.0));
        assert_eq!(wall.candela(10.0, 180.0), 9666.0);
        assert!(wall.keywords.iter().any(|(k, v)| k == "MANUFAC" && v.starts_with("H.E. WILLIAMS")));
        // The narrow spot's flux is small next to the file's lamp lumens (its reflector
        // wastes little, but most of the 4850 lm leave it outside 30°).
        let narrow = asset("narrow_spot.ies");
        assert!(narrow.lumens() > 0.0 && narrow.lumens() < 4850.0, "{}", narrow.lumens());
    }

    /// Flux against the closed form: an isotropic 1000 cd source over the lower hemisphere
    /// emits 2π·1000 lm; a cosine lobe `I₀ cos γ` emits π I₀.
    #[test]
    fn flux_matches_closed_forms() {
        let file = |values: &str, vertical: &str, n: usize| {
            format!(
                "IESNA:LM-63-2002\n[TEST] closed form\nTILT=NONE\n1 -1 1 {n} 1 1 2 0 0 0\n1 1 10\n{vertical}\n0\n{values}\n"
            )
        };
        let flat = Photometry::parse(file("1000 1000", "0 90", 2).as_bytes()).unwrap();
        assert!((flat.lumens() / (2.0 * PI * 1000.0) - 1.0).abs() < 1e-3, "{}", flat.lumens());
        let angles: Vec<String> = (0..=90).map(|g| g.to_string()).collect();
        let cosine: Vec<String> = (0..=90).map(|g| format!("{}", 500.0 * f64::from(g).to_radians().cos())).collect();
        let lobe = Photometry::parse(file(&cosine.join(" "), &angles.join(" "), 91).as_bytes()).unwrap();
        assert!((lobe.lumens() / (PI * 500.0) - 1.0).abs() < 1e-3, "{}", lobe.lumens());
    }

    /// Bad files get an error naming the problem, never a panic or a huge allocation.
    #[test]
    fn bad_files_are_refused_with_the_reason() {
        let cases = [
            ("", "no TILT= line"),
            ("IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 3 1", "ends before"),
            ("TILT=NONE\n1 -1 1 2 1 2 2 0 0 0\n1 1 1\n0 90\n0\n1 1", "type B"),
            ("TILT=NONE\n1 -1 1 99999999 99999999 1 2 0 0 0\n1 1 1\n", "number of vertical angles"),
            ("TILT=NONE\n1 -1 1 4000 4000 1 2 0 0 0\n1 1 1\n", "more than"),
            ("TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 1\n90 0\n0\n1 1", "vertical angles must rise"),
            ("TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 1\n0 90\n0\n1 -1", "negative"),
            ("TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 1\n0 90\n0\n1 x", "not a number"),
            ("TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 1\n0 90\n0\n1 inf", "not finite"),
            ("TILT=NONE\n1 -1 1e200 2 1 1 2 0 0 0\n1 1 1\n0 90\n0\n1 1e200", "over 1e9"),
            ("TILT=NONE\n1 -1 0 2 1 1 2 0 0 0\n1 1 1\n0 90\n0\n1 1", "must be positive"),
            ("TILT=NONE\n1 -1 1 2 2 1 2 0 0 0\n1 1 1\n0 90\n10 20\n1 1 1 1", "horizontal angles"),
        ];
        for (text, expected) in cases {
            let error = Photometry::parse(text.as_bytes()).expect_err(text).to_string();
            assert!(error.contains(expected), "{text:?}: {error}");
        }
    }

    /// `TILT=INCLUDE` data is skipped, and the distribution after it read.
    #[test]
    fn tilt_data_is_skipped() {
        let text = "IESNA91\nTILT=INCLUDE\n1\n3\n0 45 90\n1 0.9 0.8\n1 -1 2 2 1 1 2 0 0 0\n1 1 1\n0 90\n0\n10 5\n";
        let p = Photometry::parse(text.as_bytes()).unwrap();
        assert_eq!(p.candela(0.0, 0.0), 20.0);
        assert_eq!(p.candela(45.0, 0.0), 15.0);
    }
}
