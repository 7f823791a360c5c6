//! Summed-area tables (Crow 1984): constant-time box sums over a 2D grid, used by the RSL
//! decomposer for box-filtered BRDF lookups (Xu et al. 2006 §4).

/// Inclusive prefix sums with a zero border: `table[(y) (w+1) + x] = Σ_{x'<x, y'<y} f`.
#[derive(Clone, Debug, PartialEq)]
pub struct SummedAreaTable {
    width: usize,
    height: usize,
    table: Vec<f64>,
}

impl SummedAreaTable {
    /// Builds the table of a row-major `width × height` grid.
    pub fn new(width: usize, height: usize, values: &[f64]) -> Self {
        assert_eq!(values.len(), width * height, "expected {width}x{height} values");
        let stride = width + 1;
        let mut table = vec![0.0; stride * (height + 1)];
        for y in 0..height {
            let mut row = 0.0;
            for x in 0..width {
                row += values[y * width + x];
                table[(y + 1) * stride + x + 1] = table[y * stride + x + 1] + row;
            }
        }
        Self { width, height, table }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The corner values, row-major `(width + 1) × (height + 1)`, first row and column zero
    /// (what a GPU copy of the table uploads).
    pub fn corners(&self) -> &[f64] {
        &self.table
    }

    fn at(&self, x: usize, y: usize) -> f64 {
        self.table[y * (self.width + 1) + x]
    }

    /// Sum over texels `x0..x1 × y0..y1` (half-open; clamped to the grid).
    pub fn sum(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
        let (x1, y1) = (x1.min(self.width), y1.min(self.height));
        let (x0, y0) = (x0.min(x1), y0.min(y1));
        self.at(x1, y1) - self.at(x0, y1) - self.at(x1, y0) + self.at(x0, y0)
    }

    /// `∫∫ f` over a real rectangle in texel units, with `f` constant on each texel. The
    /// integral `S(x, y)` is bilinear inside a texel, so bilinear interpolation of the table is
    /// exact.
    pub fn integral(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
        let s = |x: f64, y: f64| self.interpolate(x, y);
        s(x1, y1) - s(x0, y1) - s(x1, y0) + s(x0, y0)
    }

    /// Mean of `f` over a real rectangle in texel units (zero-area rectangles give 0).
    pub fn average(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
        let area = (x1 - x0) * (y1 - y0);
        if area.abs() < 1e-300 { 0.0 } else { self.integral(x0, y0, x1, y1) / area }
    }

    fn interpolate(&self, x: f64, y: f64) -> f64 {
        let x = x.clamp(0.0, self.width as f64);
        let y = y.clamp(0.0, self.height as f64);
        let (ix, iy) = (
            (x.floor() as usize).min(self.width.saturating_sub(1)),
            (y.floor() as usize).min(self.height.saturating_sub(1)),
        );
        let (tx, ty) = (x - ix as f64, y - iy as f64);
        let (ix1, iy1) = ((ix + 1).min(self.width), (iy + 1).min(self.height));
        let top = self.at(ix, iy) * (1.0 - tx) + self.at(ix1, iy) * tx;
        let bottom = self.at(ix, iy1) * (1.0 - tx) + self.at(ix1, iy1) * tx;
        top * (1.0 - ty) + bottom * ty
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::test_rng;
    use rand::Rng;

    #[test]
    fn box_sums_match_brute_force() {
        let mut rng = test_rng(41);
        let (w, h) = (37, 23);
        let values: Vec<f64> = (0..w * h).map(|_| rng.random_range(-1.0..1.0)).collect();
        let sat = SummedAreaTable::new(w, h, &values);
        for _ in 0..500 {
            let (x0, x1) = (rng.random_range(0..=w), rng.random_range(0..=w));
            let (y0, y1) = (rng.random_range(0..=h), rng.random_range(0..=h));
            let (x0, x1, y0, y1) = (x0.min(x1), x0.max(x1), y0.min(y1), y0.max(y1));
            let brute: f64 = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).map(|(x, y)| values[y * w + x]).sum();
            assert!((sat.sum(x0, y0, x1, y1) - brute).abs() < 1e-10);
        }
        assert_eq!(sat.sum(5, 5, 5, 9), 0.0);
    }

    #[test]
    fn fractional_integrals_are_exact_for_piecewise_constant_texels() {
        let mut rng = test_rng(42);
        let (w, h) = (9, 7);
        let values: Vec<f64> = (0..w * h).map(|_| rng.random_range(0.0..1.0)).collect();
        let sat = SummedAreaTable::new(w, h, &values);
        for _ in 0..200 {
            let (x0, x1) = (rng.random_range(0.0..w as f64), rng.random_range(0.0..w as f64));
            let (y0, y1) = (rng.random_range(0.0..h as f64), rng.random_range(0.0..h as f64));
            let (x0, x1, y0, y1) = (x0.min(x1), x0.max(x1), y0.min(y1), y0.max(y1));
            // Exact overlap areas per texel.
            let mut brute = 0.0;
            for y in 0..h {
                for x in 0..w {
                    let ox = (x1.min(x as f64 + 1.0) - x0.max(x as f64)).max(0.0);
                    let oy = (y1.min(y as f64 + 1.0) - y0.max(y as f64)).max(0.0);
                    brute += ox * oy * values[y * w + x];
                }
            }
            assert!((sat.integral(x0, y0, x1, y1) - brute).abs() < 1e-10);
        }
        assert!(
            (sat.average(0.0, 0.0, w as f64, h as f64) - values.iter().sum::<f64>() / (w * h) as f64).abs() < 1e-12
        );
    }
}
