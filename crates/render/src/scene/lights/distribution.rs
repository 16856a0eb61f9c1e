//! Piecewise-constant distributions on `[0, 1)` and `[0, 1)²` (pbrt's `Distribution1D/2D`),
//! for importance-sampling an environment map: the 2D one is a marginal over rows and one
//! conditional per row, so a sample costs two binary searches and no allocation.
use glam::Vec2;

/// A density proportional to `func` over `n` equal cells of `[0, 1)`.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f32>,
    /// `cdf[0] = 0`, `cdf[n] = 1`, non-decreasing.
    cdf: Vec<f32>,
    /// `∫ func` over `[0, 1)`, i.e. the mean of `func`.
    integral: f64,
}

impl Distribution1D {
    /// `func` must be finite and non-negative (the caller checks). An all-zero function gets a
    /// uniform CDF (so sampling stays defined) and zero density everywhere.
    pub fn new(func: Vec<f32>) -> Distribution1D {
        let n = func.len().max(1);
        let total: f64 = func.iter().map(|&f| f as f64).sum();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut acc = 0.0f64;
        for i in 0..n {
            acc += if total > 0.0 { func.get(i).copied().unwrap_or(0.0) as f64 } else { 1.0 };
            cdf.push((acc / if total > 0.0 { total } else { n as f64 }) as f32);
        }
        cdf[n] = 1.0;
        Distribution1D { func, cdf, integral: total / n as f64 }
    }

    pub fn integral(&self) -> f64 {
        self.integral
    }

    pub fn len(&self) -> usize {
        self.func.len()
    }

    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Density of cell `i` (with respect to `x ∈ [0, 1)`).
    #[inline]
    pub fn pdf(&self, i: usize) -> f32 {
        if self.integral > 0.0 {
            (self.func[i] as f64 / self.integral) as f32
        } else {
            0.0
        }
    }

    /// `(x, cell)`: the cell whose CDF interval holds `u`, and `x` in it by linear remapping.
    #[inline]
    pub fn sample(&self, u: f32) -> (f32, usize) {
        let n = self.cdf.len() - 1;
        let i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 { ((u - self.cdf[i]) / width).clamp(0.0, 1.0) } else { 0.5 };
        (((i as f32 + du) / n as f32).min(1.0 - f32::EPSILON / 2.0), i)
    }
}

/// A density on `[0, 1)²` proportional to `func` over a `width × height` grid of cells (row
/// `0` at `v ∈ [0, 1/height)`).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    rows: Distribution1D,
    conditional: Vec<Distribution1D>,
}

impl Distribution2D {
    /// `func` is row-major, `width × height` values, finite and non-negative.
    pub fn new(func: &[f32], width: usize, height: usize) -> Distribution2D {
        let conditional: Vec<Distribution1D> = func.chunks_exact(width).take(height).map(|r| Distribution1D::new(r.to_vec())).collect();
        let rows = Distribution1D::new(conditional.iter().map(|c| c.integral() as f32).collect());
        Distribution2D { rows, conditional }
    }

    /// `∫ func` over the unit square.
    pub fn integral(&self) -> f64 {
        self.rows.integral()
    }

    /// Density at cell `(col, row)` with respect to area in `[0, 1)²`.
    #[inline]
    pub fn pdf(&self, col: usize, row: usize) -> f32 {
        self.rows.pdf(row) * self.conditional[row].pdf(col)
    }

    /// `(point, (col, row))`: `u.y` picks the row, `u.x` the column in it.
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec2, (usize, usize)) {
        let (v, row) = self.rows.sample(u.y);
        let (x, col) = self.conditional[row].sample(u.x);
        (Vec2::new(x, v), (col, row))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_d_samples_follow_the_function_and_skip_zero_cells() {
        let d = Distribution1D::new(vec![1.0, 0.0, 3.0, 0.0]);
        assert!((d.integral() - 1.0).abs() < 1e-9);
        assert_eq!((d.pdf(0), d.pdf(1), d.pdf(2)), (1.0, 0.0, 3.0));
        let n = 4000;
        let mut count = [0usize; 4];
        for k in 0..n {
            let (x, i) = d.sample((k as f32 + 0.5) / n as f32);
            assert!((x * 4.0).floor() as usize == i && (0.0..1.0).contains(&x), "{x} {i}");
            count[i] += 1;
        }
        assert_eq!(count, [1000, 0, 3000, 0]);
        // All zero: uniform sampling, zero density.
        let z = Distribution1D::new(vec![0.0; 3]);
        assert_eq!(z.sample(0.5).1, 1);
        assert_eq!(z.pdf(1), 0.0);
    }

    #[test]
    fn two_d_density_integrates_to_one_and_matches_sampling() {
        let (w, h) = (5, 3);
        let func: Vec<f32> = (0..w * h).map(|i| ((i * 7) % 4) as f32).collect();
        let d = Distribution2D::new(&func, w, h);
        let total: f32 = (0..h).flat_map(|r| (0..w).map(move |c| (c, r))).map(|(c, r)| d.pdf(c, r)).sum::<f32>() / (w * h) as f32;
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        // Stratified samples land in each cell in proportion to its density (up to one stratum
        // line of `n` samples at each row and column boundary).
        let n = 300;
        let mut count = vec![0usize; w * h];
        for a in 0..n {
            for b in 0..n {
                let (p, (c, r)) = d.sample(Vec2::new((a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32));
                assert_eq!(((p.x * w as f32) as usize, (p.y * h as f32) as usize), (c, r));
                count[r * w + c] += 1;
            }
        }
        for r in 0..h {
            for c in 0..w {
                let expect = d.pdf(c, r) as f64 / (w * h) as f64 * (n * n) as f64;
                assert!((count[r * w + c] as f64 - expect).abs() <= 2.0 * n as f64 + 2.0, "cell {c},{r}: {} vs {expect}", count[r * w + c]);
            }
        }
    }
}
