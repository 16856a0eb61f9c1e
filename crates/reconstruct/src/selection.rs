//! Choosing the control-variate pixels `Ω_c` of each centre pixel `c`.
//!
//! Candidates come from a `search_window²` window around `c`, shifted inside the image at
//! borders so that border pixels keep a full set of distinct candidates. Ties are broken by
//! spatial distance and then by position, so the choice is deterministic.
use crate::named::named_enum;
use crate::rng::hash4;
use crate::simd::{dist2, knn_key, CandidateRow, Portable, Simd, KNN_KEYS_SLACK};
use crate::window::shifted_range;
use cvtrace_streams::StreamSet;

named_enum! {
    /// How the `k` control variates of a pixel are chosen inside its search window.
    pub enum Selection: "selection" {
        /// The `k` nearest by squared CRN colour difference to the centre (the paper's choice).
        Knn => "knn",
        /// The `k` spatially nearest pixels: a 5×5 window for k = 25 (data-independent).
        Window => "window",
        /// `k` pixels drawn at random (a fixed function of the seed and the pixel).
        Random => "random",
        /// The `k` nearest by `1 − exp(−‖Δalbedo‖²)·exp(−‖Δnormal‖²)` (needs features).
        Gbuffer => "gbuffer",
    }
}

/// Largest supported search window side.
pub const MAX_SEARCH_WINDOW: usize = 31;
const MAX_CANDIDATES: usize = MAX_SEARCH_WINDOW * MAX_SEARCH_WINDOW;

/// Per-thread candidate buffer, reused for every pixel (with room for the whole vectors the
/// k-NN keys are written in).
pub struct SelectScratch {
    keys: Box<[u64; MAX_CANDIDATES + KNN_KEYS_SLACK]>,
}

impl Default for SelectScratch {
    fn default() -> Self {
        SelectScratch::new()
    }
}

impl SelectScratch {
    pub fn new() -> Self {
        SelectScratch { keys: Box::new([0; MAX_CANDIDATES + KNN_KEYS_SLACK]) }
    }
}

pub struct Selector<'a> {
    kind: Selection,
    k: usize,
    search: usize,
    include_centre: bool,
    seed: u64,
    width: usize,
    height: usize,
    crn: &'a [[f32; 3]],
    /// The CRN image as three planes (R, G, B), padded for whole-vector loads, for `Knn`.
    crn_planes: Option<[Vec<f32>; 3]>,
    albedo: Option<&'a [[f32; 3]]>,
    normal: Option<&'a [[f32; 3]]>,
}

impl<'a> Selector<'a> {
    /// `k` counts the centre when `include_centre` (ours) and only neighbours otherwise (cv).
    /// The caller has checked that features exist for `Gbuffer`.
    pub fn new(kind: Selection, k: usize, search: usize, include_centre: bool, seed: u64, set: &'a StreamSet) -> Self {
        Selector {
            kind,
            k,
            search,
            include_centre,
            seed,
            width: set.width,
            height: set.height,
            crn: &set.crn.mean.pixels,
            crn_planes: (kind == Selection::Knn).then(|| {
                std::array::from_fn(|ch| {
                    let mut plane: Vec<f32> = set.crn.mean.pixels.iter().map(|p| p[ch]).collect();
                    plane.resize(plane.len() + KNN_KEYS_SLACK, 0.0);
                    plane
                })
            }),
            albedo: set.features.as_ref().map(|f| f.albedo.pixels.as_slice()),
            normal: set.features.as_ref().map(|f| f.normal.pixels.as_slice()),
        }
    }

    /// Writes the chosen pixel indices to `out` (the centre first when included) and returns
    /// how many there are: `k`, or fewer when the image has fewer pixels.
    pub fn select(&self, x: usize, y: usize, scratch: &mut SelectScratch, out: &mut [u32]) -> usize {
        self.select_with(Portable, x, y, scratch, out)
    }

    /// [`Selector::select`] with the k-NN keys built by the vector build `simd` (the same keys,
    /// so the same selection in the same order).
    #[inline(always)]
    pub(crate) fn select_with<S: Simd>(&self, simd: S, x: usize, y: usize, scratch: &mut SelectScratch, out: &mut [u32]) -> usize {
        let (w, c) = (self.width, y * self.width + x);
        let xr = shifted_range(x, self.search, w);
        let yr = shifted_range(y, self.search, self.height);
        let span = xr.len();
        let mut n = 0;
        if let Some([r, g, b]) = &self.crn_planes {
            // The keys of a window row in whole vectors; the centre's row then closes up over
            // the centre, which is not a candidate.
            let planes = [&r[..], &g[..], &b[..]];
            for yy in yr.clone() {
                let local0 = ((yy - yr.start) * span) as u32;
                let (dx0, dy) = (xr.start as i32 - x as i32, yy as i32 - y as i32);
                let row = CandidateRow { p0: yy * w + xr.start, n: span, offset: [dx0, dy], local0 };
                simd.knn_keys(planes, self.crn[c], row, &mut scratch.keys[n..]);
                if yy == y {
                    let at = n + x - xr.start;
                    scratch.keys.copy_within(at + 1..n + span, at);
                    n += span - 1;
                } else {
                    n += span;
                }
            }
        } else {
            for yy in yr.clone() {
                for xx in xr.clone() {
                    let i = yy * w + xx;
                    if i == c {
                        continue;
                    }
                    let (dx, dy) = (xx as i64 - x as i64, yy as i64 - y as i64);
                    let spatial = (dx * dx + dy * dy) as u64;
                    let primary: u32 = match self.kind {
                        Selection::Knn => dist2(&self.crn[c], &self.crn[i]).to_bits(),
                        Selection::Window => 0,
                        Selection::Random => (hash4(self.seed, c as u64, i as u64, 0x5e1) >> 32) as u32,
                        Selection::Gbuffer => {
                            let (a, nrm) = (self.albedo.unwrap_or(&[]), self.normal.unwrap_or(&[]));
                            let g = 1.0 - (-dist2(&a[c], &a[i])).exp() * (-dist2(&nrm[c], &nrm[i])).exp();
                            g.max(0.0).to_bits()
                        }
                    };
                    // Non-negative f32 bits order like the floats; the local index makes keys unique.
                    let local = ((yy - yr.start) * span + (xx - xr.start)) as u64;
                    scratch.keys[n] = knn_key(primary, spatial, local);
                    n += 1;
                }
            }
        }
        let mut count = 0;
        if self.include_centre {
            out[0] = c as u32;
            count = 1;
        }
        let want = self.k.saturating_sub(count).min(n);
        let keys = &mut scratch.keys[..n];
        if want > 0 && want < n {
            keys.select_nth_unstable(want - 1);
        }
        for key in &keys[..want] {
            let local = (key & 0xfffff) as usize;
            out[count] = ((yr.start + local / span) * w + xr.start + local % span) as u32;
            count += 1;
        }
        count
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cvtrace_streams::{Features, Image, Stream, StreamMeta};

    fn set_with(crn: Image, albedo: Image) -> StreamSet {
        let (w, h) = (crn.width, crn.height);
        StreamSet {
            width: w,
            height: h,
            pt: Stream { mean: crn.clone(), batches: vec![] },
            crn: Stream { mean: crn, batches: vec![] },
            features: Some(Features { albedo, normal: Image::from_fn(w, h, |_, _| [0.0, 0.0, 1.0]), depth: vec![1.0; w * h] }),
            meta: StreamMeta::default(),
        }
    }

    fn chosen(sel: &Selector, x: usize, y: usize) -> Vec<u32> {
        let mut out = [0u32; 64];
        let n = sel.select(x, y, &mut SelectScratch::new(), &mut out);
        out[..n].to_vec()
    }

    #[test]
    fn window_selection_is_the_5x5_block_and_shifts_at_borders() {
        let im = Image::new(20, 20);
        let set = set_with(im.clone(), im);
        let sel = Selector::new(Selection::Window, 25, 11, true, 0, &set);
        let mut got = chosen(&sel, 10, 10);
        assert_eq!(got[0], 10 * 20 + 10);
        got.sort();
        let want: Vec<u32> = (8..13).flat_map(|y| (8..13).map(move |x| y * 20 + x)).collect();
        assert_eq!(got, want);
        // At a corner the set is still 25 distinct in-image pixels, centre first.
        let mut corner = chosen(&sel, 0, 0);
        assert_eq!(corner[0], 0);
        corner.sort();
        corner.dedup();
        assert_eq!(corner.len(), 25);
    }

    #[test]
    fn knn_prefers_similar_crn_colours_and_cv_excludes_the_centre() {
        // Left half dark, right half bright: a dark pixel near the edge picks dark pixels.
        let crn = Image::from_fn(12, 12, |x, _| if x < 6 { [0.1; 3] } else { [1.0; 3] });
        let set = set_with(crn, Image::new(12, 12));
        let sel = Selector::new(Selection::Knn, 25, 11, true, 0, &set);
        let got = chosen(&sel, 5, 6);
        assert!(got.iter().all(|&i| (i % 12) < 6), "{got:?}");
        let cv = Selector::new(Selection::Knn, 25, 11, false, 0, &set);
        let got = chosen(&cv, 5, 6);
        assert_eq!(got.len(), 25);
        assert!(!got.contains(&(6 * 12 + 5)));
    }

    #[test]
    fn gbuffer_follows_albedo_and_random_is_deterministic_and_distinct() {
        let albedo = Image::from_fn(12, 12, |_, y| if y < 6 { [0.9; 3] } else { [0.1; 3] });
        let set = set_with(Image::new(12, 12), albedo);
        let sel = Selector::new(Selection::Gbuffer, 20, 11, true, 0, &set);
        assert!(chosen(&sel, 6, 7).iter().all(|&i| i / 12 >= 6));
        let r1 = Selector::new(Selection::Random, 25, 11, true, 3, &set);
        let a = chosen(&r1, 6, 6);
        assert_eq!(a, chosen(&r1, 6, 6));
        let mut d = a.clone();
        d.sort();
        d.dedup();
        assert_eq!(d.len(), 25);
        assert_ne!(a, chosen(&Selector::new(Selection::Random, 25, 11, true, 4, &set), 6, 6));
    }

    #[test]
    fn tiny_images_give_fewer_pixels() {
        let set = set_with(Image::new(2, 2), Image::new(2, 2));
        let sel = Selector::new(Selection::Knn, 25, 11, true, 0, &set);
        assert_eq!(chosen(&sel, 1, 1).len(), 4);
    }

    #[cfg(target_arch = "x86_64")]
    fn chosen_avx2(avx2: crate::simd::Avx2, sel: &Selector, x: usize, y: usize) -> Vec<u32> {
        let mut out = [0u32; 64];
        let n = sel.select_with(avx2, x, y, &mut SelectScratch::new(), &mut out);
        out[..n].to_vec()
    }

    /// The k-NN keys built by whole window rows (both builds of the kernel) give the selection,
    /// in its order, that the per-candidate keys give: every pixel of images with ties (flat,
    /// quantised) and narrower or shorter than the window, for several windows and k.
    #[test]
    fn knn_keys_by_rows_select_what_the_per_candidate_keys_select() {
        use crate::synthetic::{RenderSpec, SoftShadowScene};
        #[cfg(target_arch = "x86_64")]
        let avx2 = crate::simd::Avx2::detect();
        let mut compared = 0;
        for (w, h) in [(37, 29), (9, 40), (40, 6)] {
            let scene = SoftShadowScene::default().render(&RenderSpec { width: w, height: h, spp: 8, batches: 4, seed: 3 }).unwrap();
            let mut quantised = scene.clone();
            quantised.crn.mean.pixels.iter_mut().for_each(|p| *p = p.map(|v| (v * 4.0).round() / 4.0));
            let mut flat = scene.clone();
            flat.crn.mean.pixels.fill([0.5; 3]);
            for set in [&scene, &quantised, &flat] {
                for (k, search, centre) in [(49, 15, true), (48, 15, false), (25, 11, true), (9, 3, true), (40, 7, false), (64, 31, true)] {
                    let rows = Selector::new(Selection::Knn, k, search, centre, 0, set);
                    let mut per_candidate = Selector::new(Selection::Knn, k, search, centre, 0, set);
                    per_candidate.crn_planes = None;
                    for y in 0..h {
                        for x in 0..w {
                            let want = chosen(&per_candidate, x, y);
                            assert_eq!(chosen(&rows, x, y), want, "portable, {w}x{h} k={k} search={search} at ({x}, {y})");
                            #[cfg(target_arch = "x86_64")]
                            if let Some(avx2) = avx2 {
                                assert_eq!(chosen_avx2(avx2, &rows, x, y), want, "AVX2, {w}x{h} k={k} search={search} at ({x}, {y})");
                            }
                            compared += 1;
                        }
                    }
                }
            }
        }
        assert!(compared > 10_000);
    }

    /// The centre-free pass of `ours`' two-stage estimate reuses the joint selection minus the
    /// centre: a `k − 1` selection without the centre must be exactly that, in the same order,
    /// also where primary keys tie (a flat image, `window`, and quantised colours).
    #[test]
    fn centre_free_selection_is_the_joint_one_after_the_centre() {
        use crate::synthetic::{RenderSpec, SoftShadowScene};
        let scene = SoftShadowScene::default().render(&RenderSpec { width: 37, height: 29, spp: 16, batches: 16, seed: 2 }).unwrap();
        let mut quantised = scene.clone();
        quantised.crn.mean.pixels.iter_mut().for_each(|p| *p = p.map(|v| (v * 4.0).round() / 4.0));
        let mut flat = scene.clone();
        flat.crn.mean.pixels.fill([0.5; 3]);
        let (mut compared, mut tied) = (0, 0);
        for set in [&scene, &quantised, &flat] {
            for kind in [Selection::Knn, Selection::Window, Selection::Random, Selection::Gbuffer] {
                for (k, search) in [(25, 11), (2, 3), (9, 3), (25, 5), (40, 7), (64, 31)] {
                    let joint = Selector::new(kind, k, search, true, 9, set);
                    let free = Selector::new(kind, k - 1, search, false, 9, set);
                    for y in 0..set.height {
                        for x in 0..set.width {
                            let a = chosen(&joint, x, y);
                            let b = chosen(&free, x, y);
                            assert_eq!(&a[1..], &b[..], "{kind:?} k={k} search={search} at ({x}, {y})");
                            compared += 1;
                            let c = set.crn.mean.pixels[y * set.width + x];
                            let d: Vec<u32> = a[1..].iter().map(|&i| dist2(&c, &set.crn.mean.pixels[i as usize]).to_bits()).collect();
                            tied += usize::from((1..d.len()).any(|j| d[..j].contains(&d[j])));
                        }
                    }
                }
            }
        }
        assert!(tied > compared / 4, "the case should include many ties: {tied} of {compared}");
    }
}
