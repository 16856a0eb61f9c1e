//! Intel Open Image Denoise on cvtrace images: the safe wrapper of its `RT` filter (linear HDR
//! colour, optionally guided by the first-hit albedo and shading normal) and of the prefilter
//! OIDN's documentation recommends for noisy guides (each guide image denoised on its own
//! first, then trusted as clean).
//!
//! A [`Denoiser`] owns one CPU device; [`Denoiser::shared`] is the one the estimators use,
//! made at the first call and kept (making a device loads OIDN's CPU module and costs more than
//! filtering a small image). Calls on one denoiser take turns (OIDN spreads each filter over
//! its threads itself). The output depends only on the input and the options: not on the
//! number of threads (a test checks it), but OIDN's kernels for different instruction sets
//! (AVX2, AVX-512) may round differently, so two CPUs can differ in the last bits.
use cvtrace_oidn_sys::oidn::{self, sys};
use cvtrace_streams::Image;
use std::ffi::{c_char, c_void, CStr};
use std::sync::Mutex;

/// OIDN's quality levels: `high` is its best (and its default for the CPU), `balanced` and
/// `fast` trade quality for speed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Quality {
    #[default]
    High,
    Balanced,
    Fast,
}

impl Quality {
    pub const NAMES: &'static [&'static str] = &["high", "balanced", "fast"];

    pub fn parse(name: &str) -> Option<Quality> {
        match name {
            "high" => Some(Quality::High),
            "balanced" => Some(Quality::Balanced),
            "fast" => Some(Quality::Fast),
            _ => None,
        }
    }

    fn raw(self) -> i32 {
        match self {
            Quality::High => sys::OIDNQuality_OIDN_QUALITY_HIGH,
            Quality::Balanced => sys::OIDNQuality_OIDN_QUALITY_BALANCED,
            Quality::Fast => sys::OIDNQuality_OIDN_QUALITY_FAST,
        }
    }
}

/// How the guide images are used.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AuxMode {
    /// No guides: the colour alone.
    None,
    /// The guides as given; OIDN assumes they are noisy and makes allowance for it.
    Raw,
    /// The guides as given, declared noise-free (OIDN's `cleanAux`): right for guides that
    /// are, such as ones rendered with many samples.
    Clean,
    /// Each guide denoised by its own filter first, then given as clean: the pipeline OIDN's
    /// documentation recommends for guides rendered with the image's own few samples.
    #[default]
    Prefiltered,
}

impl AuxMode {
    pub const NAMES: &'static [&'static str] = &["prefiltered", "raw", "clean", "none"];

    pub fn parse(name: &str) -> Option<AuxMode> {
        match name {
            "prefiltered" => Some(AuxMode::Prefiltered),
            "raw" => Some(AuxMode::Raw),
            "clean" => Some(AuxMode::Clean),
            "none" => Some(AuxMode::None),
            _ => None,
        }
    }
}

/// How to denoise.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DenoiseOptions {
    pub quality: Quality,
    pub aux: AuxMode,
}

/// The first-hit features that guide the filter.
#[derive(Clone, Copy, Debug)]
pub struct Aux<'a> {
    /// Reflectance; values above 1 (an emitter's) are clamped, as OIDN takes [0, 1].
    pub albedo: &'a Image,
    /// Shading normals, components in [−1, 1].
    pub normal: &'a Image,
}

/// Why a denoise failed, in OIDN's own words where it gave some.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    #[error("Intel Open Image Denoise: {0}")]
    Oidn(String),
    #[error("Intel Open Image Denoise: the {what} is {width}x{height}, the image {expected_width}x{expected_height}")]
    Size { what: &'static str, width: usize, height: usize, expected_width: usize, expected_height: usize },
}

impl From<oidn::Error> for DenoiseError {
    fn from(e: oidn::Error) -> Self {
        DenoiseError::Oidn(e.to_string())
    }
}

/// One OIDN CPU device and the filters run on it.
pub struct Denoiser {
    device: Mutex<oidn::Device>,
}

/// The shared denoiser, made at the first call (`None` until then).
static SHARED: Mutex<Option<&'static Denoiser>> = Mutex::new(None);

impl Denoiser {
    /// A CPU device with `threads` worker threads (`None`: OIDN's default, every core).
    pub fn cpu(threads: Option<usize>) -> Result<Denoiser, DenoiseError> {
        // SAFETY: creating a device has no preconditions; a null handle is checked below.
        let raw = unsafe { sys::oidnNewDevice(sys::OIDNDeviceType_OIDN_DEVICE_TYPE_CPU) };
        if raw.is_null() {
            return Err(DenoiseError::Oidn(format!("no CPU device ({})", device_error(std::ptr::null_mut()).unwrap_or_default())));
        }
        if let Some(n) = threads {
            let n = i32::try_from(n).unwrap_or(i32::MAX);
            // SAFETY: a valid, not yet committed device and a NUL-terminated parameter name.
            unsafe { sys::oidnSetDeviceInt(raw, c"numThreads".as_ptr(), n) };
        }
        // SAFETY: a valid device, committed once before use.
        unsafe { sys::oidnCommitDevice(raw) };
        if let Some(message) = device_error(raw) {
            // SAFETY: the device was made above and is released once.
            unsafe { sys::oidnReleaseDevice(raw) };
            return Err(DenoiseError::Oidn(message));
        }
        // SAFETY: a valid, committed device whose one reference the wrapper now owns.
        let device = unsafe { oidn::Device::from_raw(raw) };
        Ok(Denoiser { device: Mutex::new(device) })
    }

    /// The denoiser every estimator shares: OIDN's default thread count.
    pub fn shared() -> Result<&'static Denoiser, DenoiseError> {
        let mut slot = SHARED.lock().unwrap_or_else(|p| p.into_inner());
        match *slot {
            Some(d) => Ok(d),
            None => Ok(*slot.insert(Box::leak(Box::new(Denoiser::cpu(None)?)))),
        }
    }

    /// `color` (linear, HDR) denoised, guided by `aux` as `options.aux` says (guides are ignored
    /// with [`AuxMode::None`]).
    pub fn denoise(&self, color: &Image, aux: Option<Aux>, options: &DenoiseOptions) -> Result<Image, DenoiseError> {
        let aux = aux.filter(|_| options.aux != AuxMode::None);
        if let Some(a) = aux {
            check_size("albedo", a.albedo, color)?;
            check_size("normal", a.normal, color)?;
        }
        let device = self.device.lock().unwrap_or_else(|p| p.into_inner());
        let guides = match aux {
            None => None,
            Some(a) => {
                let albedo = clamped_albedo(a.albedo);
                Some(match options.aux {
                    AuxMode::Prefiltered => (
                        run_rt(&device, &[(c"albedo", &albedo)], color, false, options.quality)?,
                        run_rt(&device, &[(c"normal", a.normal)], color, false, options.quality)?,
                        true,
                    ),
                    AuxMode::Clean => (albedo, a.normal.clone(), true),
                    _ => (albedo, a.normal.clone(), false),
                })
            }
        };
        match &guides {
            None => run_rt(&device, &[(c"color", color)], color, false, options.quality),
            Some((albedo, normal, clean)) => {
                run_rt(&device, &[(c"color", color), (c"albedo", albedo), (c"normal", normal)], color, *clean, options.quality)
            }
        }
    }
}

/// Denoises with [`Denoiser::shared`].
pub fn denoise(color: &Image, aux: Option<Aux>, options: &DenoiseOptions) -> Result<Image, DenoiseError> {
    Denoiser::shared()?.denoise(color, aux, options)
}

fn check_size(what: &'static str, image: &Image, color: &Image) -> Result<(), DenoiseError> {
    if image.same_size(color) && image.pixels.len() == color.width * color.height {
        Ok(())
    } else {
        Err(DenoiseError::Size {
            what,
            width: image.width,
            height: image.height,
            expected_width: color.width,
            expected_height: color.height,
        })
    }
}

fn clamped_albedo(albedo: &Image) -> Image {
    Image { width: albedo.width, height: albedo.height, pixels: albedo.pixels.iter().map(|p| p.map(|v| v.clamp(0.0, 1.0))).collect() }
}

/// Releases a filter on every path.
struct Filter(sys::OIDNFilter);

impl Drop for Filter {
    fn drop(&mut self) {
        // SAFETY: made by oidnNewFilter and released exactly once.
        unsafe { sys::oidnReleaseFilter(self.0) };
    }
}

/// One `RT` filter over `inputs` (named images the size of `like`), into a new image: HDR when
/// it filters a colour, the guide's own mode when it prefilters a guide.
fn run_rt(
    device: &oidn::Device,
    inputs: &[(&CStr, &Image)],
    like: &Image,
    clean_aux: bool,
    quality: Quality,
) -> Result<Image, DenoiseError> {
    let (w, h) = (like.width, like.height);
    let mut output = vec![[0.0f32; 3]; w * h];
    // SAFETY: the device is valid for the wrapper's lifetime (it owns a reference).
    let raw = unsafe { device.raw() };
    // SAFETY: a valid device and a NUL-terminated filter type.
    let filter = Filter(unsafe { sys::oidnNewFilter(raw, c"RT".as_ptr()) });
    if filter.0.is_null() {
        return Err(DenoiseError::Oidn(device_error(raw).unwrap_or_else(|| "could not make an RT filter".into())));
    }
    let share = |name: &CStr, pixels: *mut [f32; 3]| {
        // SAFETY: a valid filter; `pixels` points to `w * h` packed RGB floats that outlive
        // the filter's execution below (inputs are only read, the output only written).
        unsafe {
            sys::oidnSetSharedFilterImage(filter.0, name.as_ptr(), pixels as *mut c_void, sys::OIDNFormat_OIDN_FORMAT_FLOAT3, w, h, 0, 0, 0)
        };
    };
    for (name, image) in inputs {
        share(name, image.pixels.as_ptr() as *mut [f32; 3]);
    }
    share(c"output", output.as_mut_ptr());
    // SAFETY: a valid filter and NUL-terminated parameter names.
    unsafe {
        sys::oidnSetFilterBool(filter.0, c"hdr".as_ptr(), inputs.iter().any(|(name, _)| *name == c"color"));
        sys::oidnSetFilterBool(filter.0, c"cleanAux".as_ptr(), clean_aux);
        sys::oidnSetFilterInt(filter.0, c"quality".as_ptr(), quality.raw());
        sys::oidnCommitFilter(filter.0);
    }
    if let Some(message) = device_error(raw) {
        return Err(DenoiseError::Oidn(message));
    }
    // SAFETY: a committed filter whose images are alive (see `share`).
    unsafe { sys::oidnExecuteFilter(filter.0) };
    if let Some(message) = device_error(raw) {
        return Err(DenoiseError::Oidn(message));
    }
    Ok(Image { width: w, height: h, pixels: output })
}

/// The device's pending error (or, for a null device, the last device creation's), cleared.
fn device_error(device: sys::OIDNDevice) -> Option<String> {
    let mut message: *const c_char = std::ptr::null();
    // SAFETY: a valid or null device, and a place for the message pointer.
    let code = unsafe { sys::oidnGetDeviceError(device, &mut message) };
    if code == sys::OIDNError_OIDN_ERROR_NONE {
        return None;
    }
    let text = if message.is_null() {
        String::new()
    } else {
        // SAFETY: OIDN hands back a NUL-terminated message valid until the next call on the device.
        unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned()
    };
    Some(if text.is_empty() { format!("error code {code}") } else { text })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth image plus reproducible noise, and a flat albedo and normal.
    fn noisy(w: usize, h: usize, amplitude: f32) -> (Image, Image, Image, Image) {
        let clean = Image::from_fn(w, h, |x, y| [0.2 + 0.6 * x as f32 / w as f32, 0.5, 0.3 + 0.4 * y as f32 / h as f32]);
        let mut state = 12345u32;
        let mut noise = || {
            state = state.wrapping_mul(1664525).wrapping_add(1013904223);
            (state >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        let pixels = clean.pixels.iter().map(|p| p.map(|v| (v + amplitude * noise()).max(0.0))).collect();
        let albedo = Image::from_fn(w, h, |_, _| [0.8, 0.8, 0.8]);
        let normal = Image::from_fn(w, h, |_, _| [0.0, 0.0, 1.0]);
        (clean, Image { width: w, height: h, pixels }, albedo, normal)
    }

    fn mse(a: &Image, b: &Image) -> f64 {
        a.pixels.iter().zip(&b.pixels).flat_map(|(p, q)| (0..3).map(move |c| (p[c] as f64 - q[c] as f64).powi(2))).sum::<f64>()
            / (3 * a.pixels.len()) as f64
    }

    #[test]
    fn every_aux_mode_removes_most_of_the_noise_of_a_smooth_image() {
        let (clean, noisy, albedo, normal) = noisy(64, 48, 0.4);
        let before = mse(&noisy, &clean);
        for aux in [AuxMode::None, AuxMode::Raw, AuxMode::Clean, AuxMode::Prefiltered] {
            let options = DenoiseOptions { aux, ..DenoiseOptions::default() };
            let out = denoise(&noisy, Some(Aux { albedo: &albedo, normal: &normal }), &options).unwrap();
            let after = mse(&out, &clean);
            assert!(after < 0.1 * before, "{aux:?}: denoised MSE {after:.3e} vs noisy {before:.3e}");
        }
    }

    #[test]
    fn the_output_depends_on_the_input_not_on_the_thread_count() {
        let (_, noisy, albedo, normal) = noisy(96, 64, 0.3);
        let aux = Some(Aux { albedo: &albedo, normal: &normal });
        let options = DenoiseOptions::default();
        let one = Denoiser::cpu(Some(1)).unwrap().denoise(&noisy, aux, &options).unwrap();
        let two = Denoiser::cpu(Some(2)).unwrap().denoise(&noisy, aux, &options).unwrap();
        let again = Denoiser::cpu(Some(2)).unwrap().denoise(&noisy, aux, &options).unwrap();
        assert!(one == two && two == again, "OIDN's output depends on its thread count");
    }

    #[test]
    fn aux_of_another_size_is_an_error_naming_it() {
        let (_, noisy, _, normal) = noisy(16, 8, 0.1);
        let small = Image::new(8, 8);
        let e = denoise(&noisy, Some(Aux { albedo: &small, normal: &normal }), &DenoiseOptions::default()).unwrap_err().to_string();
        assert!(e.contains("albedo is 8x8") && e.contains("16x8"), "{e}");
    }
}
