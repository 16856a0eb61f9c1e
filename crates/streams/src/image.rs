//! A linear RGB image of f32 pixels, row-major, top row first.

#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    pub fn new(width: usize, height: usize) -> Self {
        Image { width, height, pixels: vec![[0.0; 3]; width * height] }
    }

    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> [f32; 3]) -> Self {
        let mut pixels = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                pixels.push(f(x, y));
            }
        }
        Image { width, height, pixels }
    }

    #[inline]
    pub fn len(&self) -> usize {
        self.pixels.len()
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.pixels.is_empty()
    }

    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize {
        y * self.width + x
    }

    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        self.pixels[y * self.width + x]
    }

    /// One colour channel as a contiguous plane (the layout the estimators work in).
    pub fn channel(&self, c: usize) -> Vec<f32> {
        self.pixels.iter().map(|p| p[c]).collect()
    }

    /// Builds an image from three planes of equal length.
    pub fn from_channels(width: usize, height: usize, planes: [&[f32]; 3]) -> Self {
        let n = width * height;
        assert!(planes.iter().all(|p| p.len() == n), "plane length must be width*height");
        Image { width, height, pixels: (0..n).map(|i| [planes[0][i], planes[1][i], planes[2][i]]).collect() }
    }

    /// Pixel-wise mean of several images of the same size: per value, the f64 sum over the
    /// images in order (from −0, as `Iterator::sum`) times `1/n`, rounded to f32.
    pub fn mean_of(images: &[Image]) -> Image {
        assert!(!images.is_empty());
        let (w, h) = (images[0].width, images[0].height);
        assert!(images.iter().all(|im| im.pixels.len() == w * h), "mean of images of different sizes");
        let mut out = Image::new(w, h);
        let inv = 1.0 / images.len() as f64;
        // Image by image over a block of pixels: contiguous, vectorisable sums in the same order
        // as per value over the images, with the partial sums in cache.
        const BLOCK: usize = 1024;
        let mut acc = [[0.0f64; 3]; BLOCK];
        for (start, dst) in (0..w * h).step_by(BLOCK).zip(out.pixels.chunks_mut(BLOCK)) {
            let acc = &mut acc[..dst.len()];
            acc.fill([-0.0; 3]);
            for im in images {
                for (a, p) in acc.iter_mut().zip(&im.pixels[start..start + dst.len()]) {
                    for c in 0..3 {
                        a[c] += p[c] as f64;
                    }
                }
            }
            for (o, a) in dst.iter_mut().zip(acc.iter()) {
                *o = a.map(|s| (s * inv) as f32);
            }
        }
        out
    }

    /// First non-finite value, as (x, y, channel).
    pub fn find_non_finite(&self) -> Option<(usize, usize, usize)> {
        self.pixels.iter().enumerate().find_map(|(i, p)| p.iter().position(|v| !v.is_finite()).map(|c| (i % self.width, i / self.width, c)))
    }

    pub fn same_size(&self, other: &Image) -> bool {
        self.width == other.width && self.height == other.height
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blocked mean against the per-value definition, bit for bit: sizes across block
    /// boundaries, one to five images, signed zeros, and values of very different magnitude.
    #[test]
    fn mean_of_is_the_per_value_mean() {
        let value = |k: usize, i: usize, c: usize| -> f32 {
            let h = (k * 7919 + i * 104_729 + c * 15_485_863) % 1_000_003;
            match h % 7 {
                0 => -0.0,
                1 => 0.0,
                2 => (h as f32) * 1e-7,
                3 => -(h as f32) * 3e3,
                _ => (h as f32).sqrt() * 0.1,
            }
        };
        for (w, h) in [(1usize, 1usize), (33, 31), (1024, 1), (45, 50)] {
            for n in 1..=5 {
                let images: Vec<Image> =
                    (0..n).map(|k| Image::from_fn(w, h, |x, y| std::array::from_fn(|c| value(k, y * w + x, c)))).collect();
                let got = Image::mean_of(&images);
                for i in 0..w * h {
                    for c in 0..3 {
                        let s: f64 = images.iter().map(|im| im.pixels[i][c] as f64).sum();
                        let want = (s * (1.0 / n as f64)) as f32;
                        assert_eq!(got.pixels[i][c].to_bits(), want.to_bits(), "{w}×{h}, {n} images, pixel {i} channel {c}");
                    }
                }
            }
        }
    }
}
