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

    /// Pixel-wise mean of several images of the same size.
    pub fn mean_of(images: &[Image]) -> Image {
        assert!(!images.is_empty());
        let (w, h) = (images[0].width, images[0].height);
        let mut out = Image::new(w, h);
        let inv = 1.0 / images.len() as f64;
        for i in 0..w * h {
            for c in 0..3 {
                let s: f64 = images.iter().map(|im| im.pixels[i][c] as f64).sum();
                out.pixels[i][c] = (s * inv) as f32;
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
