//! Embree as cvtrace's ray caster: the safe wrapper of `cvtrace-embree-sys`, and the only
//! crate with `unsafe` Embree calls.
//!
//! A [`Device`] wraps `RTCDevice` with an error callback installed once. Errors are
//! collected there and checked after each build step, never per ray: a committed
//! [`EmbreeScene`] is immutable, `Send + Sync`, and implements
//! [`cvtrace_render::Intersector`] through the sys crate's calls that hide the Embree 3 /
//! Embree 4 differences. [`traversal_check`] compares fast and robust traversal ray by ray.
mod denormals;
mod quads;
pub mod traversal_check;

use cvtrace_embree_sys as ffi;
pub use denormals::{flush_denormals_enabled, set_flush_denormals};

use cvtrace_render::{Hit, HitPacket, Intersector, Ray, RayPacket, PACKET};
use glam::Vec3A;
use std::ffi::{c_char, c_void, CStr};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What can go wrong while creating a device or building a scene.
#[derive(Debug, thiserror::Error)]
pub enum EmbreeError {
    #[error("could not create the Embree device: {message}")]
    Device { message: String },
    #[error("Embree failed in {call}: {message}")]
    Api { call: &'static str, message: String },
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
}

/// How much time Embree spends on the BVH versus how fast it traverses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BuildQuality {
    Low,
    Medium,
    /// Spatial splits: slower to build, fastest to trace. Right for static scenes.
    #[default]
    High,
}

/// Scene build settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BuildOptions {
    pub quality: BuildQuality,
    /// Watertight-leaning intersection that avoids precision-reducing shortcuts:
    /// fewer rays leaking through shared edges, at a few percent of speed.
    pub robust: bool,
    /// Smaller BVH memory footprint at some traversal cost.
    pub compact: bool,
    /// Hand Embree consecutive triangles that share an edge as one quad (see `quads.rs`):
    /// the same hits, traced faster. Off only to measure the difference.
    pub quads: bool,
    /// Trace the wavefront's chunks of continuation and shadow rays as Embree packets
    /// (`rtcIntersect16`/`rtcOccluded16`, or two 8-wide calls without AVX-512) rather than
    /// one ray at a time: the same answers, bit for bit, either way.
    pub packets: bool,
}

/// Embree's defaults, and cvtrace's: high quality, fast (not watertight) traversal, quads.
impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions { quality: BuildQuality::High, robust: false, compact: false, quads: true, packets: true }
    }
}

/// The first error Embree reported through its callback since the last check.
#[derive(Default)]
struct ErrorSink {
    message: Mutex<Option<String>>,
}

/// Called by Embree on any API error. It must not unwind into C, so it only logs and records.
unsafe extern "C" fn on_embree_error(user: *mut c_void, code: ffi::RTCError, text: *const c_char) {
    // SAFETY: Embree passes a NUL-terminated message (or null) valid for this call.
    let detail = if text.is_null() { String::new() } else { unsafe { CStr::from_ptr(text) }.to_string_lossy().into_owned() };
    let message = format!("{} ({detail})", error_name(code));
    tracing::error!("Embree: {message}");
    // SAFETY: `user` is the `ErrorSink` the device was created with (or null), and it outlives
    // the device.
    if let Some(sink) = unsafe { (user as *const ErrorSink).as_ref() } {
        if let Ok(mut slot) = sink.message.lock() {
            slot.get_or_insert(message);
        }
    }
}

fn error_name(code: ffi::RTCError) -> &'static str {
    match code {
        ffi::RTCError::RTC_ERROR_NONE => "no error",
        ffi::RTCError::RTC_ERROR_INVALID_ARGUMENT => "invalid argument",
        ffi::RTCError::RTC_ERROR_INVALID_OPERATION => "invalid operation",
        ffi::RTCError::RTC_ERROR_OUT_OF_MEMORY => "out of memory",
        ffi::RTCError::RTC_ERROR_UNSUPPORTED_CPU => "unsupported CPU",
        ffi::RTCError::RTC_ERROR_CANCELLED => "cancelled",
        _ => "unknown error",
    }
}

struct DeviceInner {
    raw: ffi::RTCDevice,
    // Boxed so its address, handed to Embree as the callback's user pointer, never moves.
    // Dropped after `raw` is released (fields drop after `Drop::drop`).
    sink: Box<ErrorSink>,
}

// SAFETY: Embree devices are thread-safe; the sink is behind a Mutex.
unsafe impl Send for DeviceInner {}
// SAFETY: as for Send: the device handle may be used from any thread at once.
unsafe impl Sync for DeviceInner {}

impl Drop for DeviceInner {
    fn drop(&mut self) {
        // SAFETY: `raw` came from rtcNewDevice and is released exactly once; scenes hold an Arc.
        unsafe { ffi::rtcReleaseDevice(self.raw) };
    }
}

/// An Embree device: one per process is plenty. Cheap to clone (shared handle).
#[derive(Clone)]
pub struct Device {
    inner: Arc<DeviceInner>,
}

impl Device {
    /// Creates a device and installs the error callback. Embree's defaults apply unless the
    /// environment variable `CVTRACE_EMBREE_CONFIG` holds an Embree config string
    /// (e.g. `verbose=1` to print the ISA Embree selected, `threads=1`).
    pub fn new() -> Result<Device, EmbreeError> {
        match std::env::var("CVTRACE_EMBREE_CONFIG") {
            Ok(config) if !config.trim().is_empty() => Device::with_config(&config),
            _ => Device::with_config(""),
        }
    }

    /// Creates a device with an explicit Embree config string ("" for the defaults).
    pub fn with_config(config: &str) -> Result<Device, EmbreeError> {
        let config_c = std::ffi::CString::new(config)
            .map_err(|_| EmbreeError::Device { message: format!("config string {config:?} contains a NUL byte") })?;
        let config_ptr = if config.is_empty() { std::ptr::null() } else { config_c.as_ptr() };
        // SAFETY: a null pointer selects the defaults; otherwise a valid NUL-terminated string.
        let raw = unsafe { ffi::rtcNewDevice(config_ptr) };
        if raw.is_null() {
            // SAFETY: rtcGetDeviceError(NULL) reports the error of the failed device creation.
            let code = unsafe { ffi::rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(EmbreeError::Device { message: format!("{} (config {config:?})", error_name(code)) });
        }
        let sink = Box::new(ErrorSink::default());
        // SAFETY: the sink outlives the device (see DeviceInner), and the callback never unwinds.
        unsafe { ffi::rtcSetDeviceErrorFunction(raw, Some(on_embree_error), &*sink as *const ErrorSink as *mut c_void) };
        let device = Device { inner: Arc::new(DeviceInner { raw, sink }) };
        // SAFETY: valid device; the property is a plain integer query.
        let version = unsafe { ffi::rtcGetDeviceProperty(raw, ffi::RTCDeviceProperty::RTC_DEVICE_PROPERTY_VERSION) };
        tracing::debug!(
            "Embree {}.{}.{} device ({}; bindings for Embree {})",
            version / 10000,
            version / 100 % 100,
            version % 100,
            ffi::ORIGIN,
            ffi::MAJOR
        );
        Ok(device)
    }

    /// Turns a pending Embree error (if any) into an `Err` naming the failed call.
    fn check(&self, call: &'static str) -> Result<(), EmbreeError> {
        // SAFETY: valid device; reading and clearing its sticky error code.
        let code = unsafe { ffi::rtcGetDeviceError(self.inner.raw) };
        let recorded = self.inner.sink.message.lock().ok().and_then(|mut m| m.take());
        if code == ffi::RTCError::RTC_ERROR_NONE && recorded.is_none() {
            return Ok(());
        }
        let message = recorded.unwrap_or_else(|| error_name(code).to_string());
        Err(EmbreeError::Api { call, message })
    }

    /// Builds a BVH over one triangle mesh and commits it.
    ///
    /// `triangles[i]` indexes `positions`; the resulting hits report `prim = i`.
    /// An empty mesh is allowed (every ray misses).
    pub fn build_scene(&self, positions: &[Vec3A], triangles: &[[u32; 3]], options: &BuildOptions) -> Result<EmbreeScene, EmbreeError> {
        validate_mesh(positions, triangles)?;
        let start = Instant::now();
        // SAFETY: valid device.
        let raw = unsafe { ffi::rtcNewScene(self.inner.raw) };
        if raw.is_null() {
            self.check("rtcNewScene")?;
            return Err(EmbreeError::Api { call: "rtcNewScene", message: "returned no scene".into() });
        }
        // From here on the scene is released on every error path by EmbreeScene's Drop.
        let mut scene = EmbreeScene {
            raw,
            device: self.clone(),
            triangle_count: triangles.len(),
            quad_halves: None,
            packets: options.packets,
            packet_hits: options.packets && (options.robust || !options.quads),
            build_time: Duration::ZERO,
        };
        let mut flags = ffi::RTCSceneFlags::RTC_SCENE_FLAG_NONE;
        if options.robust {
            flags |= ffi::RTCSceneFlags::RTC_SCENE_FLAG_ROBUST;
        }
        if options.compact {
            flags |= ffi::RTCSceneFlags::RTC_SCENE_FLAG_COMPACT;
        }
        let quality = match options.quality {
            BuildQuality::Low => ffi::RTCBuildQuality::RTC_BUILD_QUALITY_LOW,
            BuildQuality::Medium => ffi::RTCBuildQuality::RTC_BUILD_QUALITY_MEDIUM,
            BuildQuality::High => ffi::RTCBuildQuality::RTC_BUILD_QUALITY_HIGH,
        };
        // SAFETY: valid scene handle.
        unsafe {
            ffi::rtcSetSceneFlags(raw, flags);
            ffi::rtcSetSceneBuildQuality(raw, quality);
        }
        self.check("rtcSetSceneFlags/rtcSetSceneBuildQuality")?;
        if triangles.is_empty() {
            // Nothing to attach: every ray misses.
        } else if options.quads {
            let mesh = quads::pair_triangles(triangles);
            self.attach_mesh(raw, positions, MeshIndices::Quads(&mesh.quads), quality)?;
            scene.quad_halves = Some(mesh.halves);
        } else {
            self.attach_mesh(raw, positions, MeshIndices::Triangles(triangles), quality)?;
        }
        // SAFETY: valid scene; commit builds the BVH (Embree may use its own worker threads).
        unsafe { ffi::rtcCommitScene(raw) };
        self.check("rtcCommitScene")?;
        scene.build_time = start.elapsed();
        tracing::info!(
            "BVH built: {} triangles{} in {:.1} ms ({:?} quality{})",
            triangles.len(),
            scene.quad_halves.as_ref().map(|h| format!(" as {} quads", h.0.len())).unwrap_or_default(),
            scene.build_time.as_secs_f64() * 1e3,
            options.quality,
            if options.robust { ", robust" } else { "" }
        );
        Ok(scene)
    }

    /// Creates the triangle or quad geometry, copies the buffers into Embree-owned (padded)
    /// memory, and attaches it to `scene` as geometry 0.
    fn attach_mesh(
        &self,
        scene: ffi::RTCScene,
        positions: &[Vec3A],
        indices: MeshIndices,
        quality: ffi::RTCBuildQuality,
    ) -> Result<(), EmbreeError> {
        let (geometry_type, index_format, per_primitive, flat_indices) = match indices {
            MeshIndices::Triangles(t) => {
                (ffi::RTCGeometryType::RTC_GEOMETRY_TYPE_TRIANGLE, ffi::RTCFormat::RTC_FORMAT_UINT3, 3, t.as_flattened())
            }
            MeshIndices::Quads(q) => (ffi::RTCGeometryType::RTC_GEOMETRY_TYPE_QUAD, ffi::RTCFormat::RTC_FORMAT_UINT4, 4, q.as_flattened()),
        };
        // SAFETY: valid device.
        let geom = unsafe { ffi::rtcNewGeometry(self.inner.raw, geometry_type) };
        if geom.is_null() {
            self.check("rtcNewGeometry")?;
            return Err(EmbreeError::Api { call: "rtcNewGeometry", message: "returned no geometry".into() });
        }
        // Releases our reference on every path; after attach the scene holds its own.
        struct GeometryRef(ffi::RTCGeometry);
        impl Drop for GeometryRef {
            fn drop(&mut self) {
                // SAFETY: created by rtcNewGeometry above and released exactly once.
                unsafe { ffi::rtcReleaseGeometry(self.0) };
            }
        }
        let geom = GeometryRef(geom);
        let stride = 3 * std::mem::size_of::<f32>();
        // SAFETY: valid geometry; Embree allocates `positions.len()` float3 items plus the
        // padding its SIMD loads need, and returns null on failure.
        let vertices = unsafe {
            ffi::rtcSetNewGeometryBuffer(
                geom.0,
                ffi::RTCBufferType::RTC_BUFFER_TYPE_VERTEX,
                0,
                ffi::RTCFormat::RTC_FORMAT_FLOAT3,
                stride,
                positions.len(),
            )
        } as *mut f32;
        if vertices.is_null() {
            self.check("rtcSetNewGeometryBuffer(vertex)")?;
            return Err(EmbreeError::Api { call: "rtcSetNewGeometryBuffer(vertex)", message: "returned no buffer".into() });
        }
        // SAFETY: the buffer holds at least 3 * positions.len() floats, exclusively ours until commit.
        let dst = unsafe { std::slice::from_raw_parts_mut(vertices, 3 * positions.len()) };
        for (d, p) in dst.chunks_exact_mut(3).zip(positions) {
            d.copy_from_slice(&[p.x, p.y, p.z]);
        }
        // SAFETY: as above, for the primitives' `per_primitive` u32 each.
        let indices = unsafe {
            ffi::rtcSetNewGeometryBuffer(
                geom.0,
                ffi::RTCBufferType::RTC_BUFFER_TYPE_INDEX,
                0,
                index_format,
                per_primitive * std::mem::size_of::<u32>(),
                flat_indices.len() / per_primitive,
            )
        } as *mut u32;
        if indices.is_null() {
            self.check("rtcSetNewGeometryBuffer(index)")?;
            return Err(EmbreeError::Api { call: "rtcSetNewGeometryBuffer(index)", message: "returned no buffer".into() });
        }
        // SAFETY: the buffer holds flat_indices.len() u32, exclusively ours until commit.
        let dst = unsafe { std::slice::from_raw_parts_mut(indices, flat_indices.len()) };
        dst.copy_from_slice(flat_indices);
        // SAFETY: valid geometry and scene handles.
        unsafe {
            ffi::rtcSetGeometryBuildQuality(geom.0, quality);
            ffi::rtcCommitGeometry(geom.0);
            ffi::rtcAttachGeometry(scene, geom.0);
        }
        self.check("rtcCommitGeometry/rtcAttachGeometry")
    }
}

/// The index buffer of the one geometry a scene holds.
enum MeshIndices<'a> {
    Triangles(&'a [[u32; 3]]),
    Quads(&'a [[u32; 4]]),
}

/// Rejects what Embree would silently mis-handle: out-of-range indices (undefined
/// behaviour inside Embree) and non-finite vertices (triangles silently dropped).
fn validate_mesh(positions: &[Vec3A], triangles: &[[u32; 3]]) -> Result<(), EmbreeError> {
    if positions.len() > u32::MAX as usize || triangles.len() > u32::MAX as usize {
        return Err(EmbreeError::InvalidMesh(format!(
            "{} vertices / {} triangles exceed Embree's 32-bit limits",
            positions.len(),
            triangles.len()
        )));
    }
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(EmbreeError::InvalidMesh(format!("vertex {i} is not finite: {:?}", positions[i])));
    }
    let n = positions.len() as u32;
    if let Some((i, t)) = triangles.iter().enumerate().find(|(_, t)| t.iter().any(|&v| v >= n)) {
        return Err(EmbreeError::InvalidMesh(format!("triangle {i} references vertices {t:?} but the mesh has only {n} vertices")));
    }
    Ok(())
}

/// Embree wants 16-byte aligned ray structures; this guarantees it whatever bindgen emits.
#[repr(C, align(16))]
struct AlignedRayHit(ffi::RTCRayHit);

#[repr(C, align(16))]
struct AlignedRay(ffi::RTCRay);

/// A ray-hit record for `ray` with no hit yet.
#[inline]
fn to_rtc_rayhit(ray: &Ray) -> AlignedRayHit {
    let mut rh = AlignedRayHit(ffi::RTCRayHit {
        ray: to_rtc_ray(ray),
        hit: ffi::RTCHit { geomID: ffi::RTC_INVALID_GEOMETRY_ID, ..Default::default() },
    });
    rh.0.hit.instID.fill(ffi::RTC_INVALID_GEOMETRY_ID);
    rh
}

#[inline]
fn to_rtc_ray(ray: &Ray) -> ffi::RTCRay {
    ffi::RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        tnear: ray.tmin,
        dir_x: ray.dir.x,
        dir_y: ray.dir.y,
        dir_z: ray.dir.z,
        tfar: ray.tmax,
        // A zero mask would match no geometry at all.
        mask: u32::MAX,
        ..Default::default()
    }
}

/// A committed BVH: immutable, shareable across threads, released on drop.
pub struct EmbreeScene {
    raw: ffi::RTCScene,
    /// Keeps the device (and its error callback's sink) alive as long as the scene.
    device: Device,
    triangle_count: usize,
    /// Present when the geometry is quads: maps Embree's quad hits back to triangles.
    quad_halves: Option<quads::QuadHalves>,
    /// Whether packets go to Embree's packet calls ([`BuildOptions::packets`]).
    packets: bool,
    /// Whether Embree's packet calls give the nearest hits of its single-ray call bit for bit:
    /// with robust traversal, or triangles (with fast traversal, its packet kernel for quads
    /// rounds the barycentrics differently in the last bits; occlusion agrees either way).
    packet_hits: bool,
    build_time: Duration,
}

// SAFETY: after rtcCommitScene, Embree scenes are read-only and safe to query from any thread.
unsafe impl Send for EmbreeScene {}
// SAFETY: as for Send: concurrent queries of a committed scene are what Embree is made for.
unsafe impl Sync for EmbreeScene {}

impl EmbreeScene {
    /// Builds on a fresh device with default options: the one-liner for most callers.
    pub fn build(positions: &[Vec3A], triangles: &[[u32; 3]]) -> Result<EmbreeScene, EmbreeError> {
        Device::new()?.build_scene(positions, triangles, &BuildOptions::default())
    }

    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Wall time of the BVH build (rtcCommitScene and buffer setup).
    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    pub fn device(&self) -> &Device {
        &self.device
    }

    /// The hit Embree wrote into `rh`, in terms of the scene's triangles.
    #[inline]
    fn hit_of(&self, rh: &AlignedRayHit) -> Option<Hit> {
        let hit = &rh.0.hit;
        if hit.geomID == ffi::RTC_INVALID_GEOMETRY_ID {
            return None;
        }
        let (prim, u, v) = match &self.quad_halves {
            Some(halves) => halves.triangle_hit(hit.primID, hit.u, hit.v),
            None => (hit.primID, hit.u, hit.v),
        };
        // Embree sets tfar to the hit distance.
        Some(Hit { t: rh.0.ray.tfar, prim, u, v })
    }
}

/// Whether packets go to Embree as one 16-wide call (CPUs with AVX-512, where Embree's
/// 16-wide kernels run natively) or as two 8-wide ones.
fn sixteen_wide() -> bool {
    static WIDE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    #[cfg(target_arch = "x86_64")]
    return *WIDE.get_or_init(|| std::is_x86_feature_detected!("avx512f"));
    #[cfg(not(target_arch = "x86_64"))]
    return *WIDE.get_or_init(|| false);
}

/// The packet calls of one width `$n` on lanes `l0..l0 + $n` of a [`RayPacket`], in a module of
/// their own.
macro_rules! packet_width {
    ($m:ident, $n:literal, $valid:ident, $rayhit:ident, $ray:ident, $intersect:ident, $occluded:ident) => {
        mod $m {
            use super::*;

            /// Embree's lane masks of the active lanes `l0..l0 + N`, or `None` when none is.
            #[inline]
            fn valid(active: u16, l0: usize) -> Option<ffi::$valid> {
                let bits = (u32::from(active) >> l0) & ((1u32 << $n) - 1);
                (bits != 0).then(|| ffi::$valid(std::array::from_fn(|l| if bits >> l & 1 != 0 { -1 } else { 0 })))
            }

            /// The rays of lanes `l0..l0 + N`, as Embree's packet of that width.
            #[inline]
            fn ray_lanes(rays: &RayPacket, l0: usize) -> ffi::$ray {
                let lanes = |a: &[f32; PACKET]| -> [f32; $n] { a[l0..l0 + $n].try_into().expect("lanes within the packet") };
                ffi::$ray {
                    org_x: lanes(&rays.origin[0]),
                    org_y: lanes(&rays.origin[1]),
                    org_z: lanes(&rays.origin[2]),
                    tnear: lanes(&rays.tmin),
                    dir_x: lanes(&rays.dir[0]),
                    dir_y: lanes(&rays.dir[1]),
                    dir_z: lanes(&rays.dir[2]),
                    tfar: lanes(&rays.tmax),
                    // A zero mask would match no geometry at all.
                    mask: [u32::MAX; $n],
                    ..Default::default()
                }
            }

            /// The nearest hits of the active lanes among `l0..l0 + N` into `hits`.
            #[inline]
            pub(super) fn intersect(scene: &EmbreeScene, rays: &RayPacket, active: u16, l0: usize, hits: &mut HitPacket) {
                let Some(valid) = valid(active, l0) else { return };
                let mut rh = ffi::$rayhit { ray: ray_lanes(rays, l0), ..Default::default() };
                rh.hit.geomID = [ffi::RTC_INVALID_GEOMETRY_ID; $n];
                for id in &mut rh.hit.instID {
                    id.fill(ffi::RTC_INVALID_GEOMETRY_ID);
                }
                // SAFETY: committed scene; `valid` holds the packet's lane masks and `rh` is an
                // initialised packet of the same width, aligned as its type requires.
                unsafe { ffi::$intersect(scene.raw, &valid, &mut rh) };
                for l in (0..$n).filter(|&l| valid.0[l] != 0 && rh.hit.geomID[l] != ffi::RTC_INVALID_GEOMETRY_ID) {
                    let (prim, u, v) = match &scene.quad_halves {
                        Some(halves) => halves.triangle_hit(rh.hit.primID[l], rh.hit.u[l], rh.hit.v[l]),
                        None => (rh.hit.primID[l], rh.hit.u[l], rh.hit.v[l]),
                    };
                    // Embree sets tfar to the hit distance.
                    hits.set(l0 + l, Some(Hit { t: rh.ray.tfar[l], prim, u, v }));
                }
            }

            /// The occluded ones of the active lanes among `l0..l0 + N`, as a mask of packet lanes.
            #[inline]
            pub(super) fn occluded(scene: &EmbreeScene, rays: &RayPacket, active: u16, l0: usize) -> u16 {
                let Some(valid) = valid(active, l0) else { return 0 };
                let mut r = ray_lanes(rays, l0);
                // SAFETY: committed scene; `valid` holds the packet's lane masks and `r` is an
                // initialised ray packet of the same width, aligned as its type requires.
                unsafe { ffi::$occluded(scene.raw, &valid, &mut r) };
                // Embree marks an occluded ray by setting tfar to -inf.
                (0..$n).filter(|&l| valid.0[l] != 0 && r.tfar[l] == f32::NEG_INFINITY).fold(0, |m, l| m | 1 << (l0 + l))
            }
        }
    };
}

packet_width!(packet8, 8, Valid8, RTCRayHit8, RTCRay8, intersect8, occluded8);
packet_width!(packet16, 16, Valid16, RTCRayHit16, RTCRay16, intersect16, occluded16);

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: `raw` came from rtcNewScene and is released exactly once.
        unsafe { ffi::rtcReleaseScene(self.raw) };
    }
}

impl Intersector for EmbreeScene {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut rh = to_rtc_rayhit(ray);
        // SAFETY: committed scene; `rh` is a properly initialised, 16-byte aligned RTCRayHit.
        unsafe { ffi::intersect1(self.raw, &mut rh.0) };
        self.hit_of(&rh)
    }

    fn intersect_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        // On the stack, in chunks: no allocation per call.
        const CHUNK: usize = 64;
        let mut buf: [AlignedRayHit; CHUNK] = std::array::from_fn(|_| AlignedRayHit(Default::default()));
        for (rays, hits) in rays.chunks(CHUNK).zip(hits.chunks_mut(CHUNK)) {
            for (slot, ray) in buf.iter_mut().zip(rays) {
                *slot = to_rtc_rayhit(ray);
            }
            // SAFETY: committed scene; the first `rays.len()` entries of `buf` are initialised,
            // 16-byte aligned RTCRayHits, `size_of::<AlignedRayHit>()` bytes apart.
            unsafe { ffi::intersect_coherent(self.raw, &mut buf[0].0, rays.len() as u32, std::mem::size_of::<AlignedRayHit>()) };
            for (hit, rh) in hits.iter_mut().zip(&buf) {
                *hit = self.hit_of(rh);
            }
        }
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        let mut r = AlignedRay(to_rtc_ray(ray));
        // SAFETY: committed scene; `r` is a properly initialised, 16-byte aligned RTCRay.
        unsafe { ffi::occluded1(self.raw, &mut r.0) };
        // Embree marks an occluded ray by setting tfar to -inf.
        r.0.tfar == f32::NEG_INFINITY
    }

    fn intersect_packet(&self, rays: &RayPacket, active: u16) -> HitPacket {
        let mut hits = HitPacket::default();
        if !self.packet_hits {
            for l in (0..PACKET).filter(|l| active >> l & 1 != 0) {
                hits.set(l, self.intersect(&rays.ray(l)));
            }
        } else if sixteen_wide() {
            packet16::intersect(self, rays, active, 0, &mut hits);
        } else {
            packet8::intersect(self, rays, active, 0, &mut hits);
            packet8::intersect(self, rays, active, 8, &mut hits);
        }
        hits
    }

    fn occluded_packet(&self, rays: &RayPacket, active: u16) -> u16 {
        if !self.packets {
            (0..PACKET).filter(|&l| active >> l & 1 != 0 && self.occluded(&rays.ray(l))).fold(0, |m, l| m | 1 << l)
        } else if sixteen_wide() {
            packet16::occluded(self, rays, active, 0)
        } else {
            packet8::occluded(self, rays, active, 0) | packet8::occluded(self, rays, active, 8)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_indices_are_rejected_before_embree_sees_them() {
        let p = [Vec3A::ZERO, Vec3A::X, Vec3A::Y];
        let e = EmbreeScene::build(&p, &[[0, 1, 3]]).err().expect("out-of-range index must fail").to_string();
        assert!(e.contains("triangle 0") && e.contains("3 vertices"), "{e}");
    }

    #[test]
    fn non_finite_vertex_is_rejected() {
        let p = [Vec3A::ZERO, Vec3A::new(f32::NAN, 0.0, 0.0), Vec3A::Y];
        let e = EmbreeScene::build(&p, &[[0, 1, 2]]).err().expect("NaN vertex must fail").to_string();
        assert!(e.contains("vertex 1"), "{e}");
    }

    #[test]
    fn empty_scene_misses_everything() {
        let s = EmbreeScene::build(&[], &[]).unwrap();
        let r = Ray { origin: Vec3A::ZERO, dir: Vec3A::Z, tmin: 0.0, tmax: f32::INFINITY };
        assert!(s.intersect(&r).is_none());
        assert!(!s.occluded(&r));
    }

    #[test]
    fn ray_structs_are_aligned() {
        assert_eq!(std::mem::align_of::<AlignedRayHit>() % 16, 0);
        assert_eq!(std::mem::align_of::<AlignedRay>() % 16, 0);
    }

    #[test]
    fn the_library_writes_no_further_than_the_bindings_ray_structures_reach() {
        // A library built with more instance fields than the bindings declare would write past
        // the end of a ray: the bytes after it must come back untouched.
        const SENTINEL: u8 = 0xa5;
        let s = EmbreeScene::build(&[Vec3A::ZERO, Vec3A::X, Vec3A::Y], &[[0, 1, 2]]).unwrap();
        let ray = Ray { origin: Vec3A::new(0.25, 0.25, 1.0), dir: -Vec3A::Z, tmin: 0.0, tmax: f32::INFINITY };
        #[repr(C)]
        struct Guarded<T> {
            value: T,
            after: [u8; 64],
        }
        let mut rh = Guarded { value: to_rtc_rayhit(&ray), after: [SENTINEL; 64] };
        // SAFETY: committed scene; an initialised, aligned ray-hit record.
        unsafe { ffi::intersect1(s.raw, &mut rh.value.0) };
        assert_eq!((rh.value.0.hit.geomID, rh.value.0.hit.primID), (0, 0));
        assert!(rh.after.iter().all(|&b| b == SENTINEL), "Embree wrote past RTCRayHit");
        let mut r = Guarded { value: AlignedRay(to_rtc_ray(&ray)), after: [SENTINEL; 64] };
        // SAFETY: committed scene; an initialised, aligned ray.
        unsafe { ffi::occluded1(s.raw, &mut r.value.0) };
        assert_eq!(r.value.0.tfar, f32::NEG_INFINITY);
        assert!(r.after.iter().all(|&b| b == SENTINEL), "Embree wrote past RTCRay");
        let mut batch = Guarded { value: [to_rtc_rayhit(&ray), to_rtc_rayhit(&ray)], after: [SENTINEL; 64] };
        // SAFETY: committed scene; two initialised, aligned records one record apart.
        unsafe { ffi::intersect_coherent(s.raw, &mut batch.value[0].0, 2, std::mem::size_of::<AlignedRayHit>()) };
        assert!(batch.value.iter().all(|rh| rh.0.hit.geomID == 0));
        assert!(batch.after.iter().all(|&b| b == SENTINEL), "Embree wrote past the coherent batch");
    }

    #[test]
    fn the_library_is_the_major_version_of_the_bindings() {
        let device = Device::new().unwrap();
        // SAFETY: a valid device; the property is a plain integer query.
        let version = unsafe { ffi::rtcGetDeviceProperty(device.inner.raw, ffi::RTCDeviceProperty::RTC_DEVICE_PROPERTY_VERSION) };
        assert_eq!(version / 10000, ffi::MAJOR as isize, "Embree {version} loaded, bindings for {} ({})", ffi::MAJOR, ffi::ORIGIN);
        assert_eq!(ffi::RTC_VERSION_MAJOR, ffi::MAJOR);
    }
}
