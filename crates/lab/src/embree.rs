//! Intel Embree 3 as a comparison engine (feature `embree`): the same triangles and rays as
//! quiver's kernels, in the same process, so `quiver bench` and `quiver packets` can time the
//! two side by side. A small hand-written FFI against the system's `libembree3` (Debian:
//! `apt-get install libembree-dev`), checked against the 3.13 headers, rather than a bindings
//! crate: the few calls used here are all we need, and every layout is asserted below.
//!
//! ```
//! use glam::Vec3A;
//! use quiver_rt::{Ray, Triangle};
//! use quiver_lab::embree::EmbreeScene;
//! let tris = [Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
//! let scene = EmbreeScene::new(&tris).unwrap();
//! let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
//! assert_eq!(scene.closest_hit(&ray), Some((0, 1.0))); // (triangle index, t)
//! assert!(scene.any_hit(&ray));
//! ```
//!
//! Embree's triangle test is not quiver's (Embree accepts `tnear < t <= tfar`, quiver the
//! closed interval, and the two round differently on edges), and on ties Embree returns any of
//! the tied triangles, quiver the lowest index: the two may disagree on rays through edges and
//! at equal distances (the tests below allow one ray in 1,000).

use glam::{Affine3A, Vec3A};
use quiver_rt::{Ray, Triangle};
use std::ffi::{c_char, c_void, CStr, CString};
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex};

/// The subset of `embree3/rtcore*.h` (3.13) used here. Names follow the C headers.
#[allow(
    non_camel_case_types,
    non_snake_case,
    clippy::upper_case_acronyms,
    dead_code
)]
mod ffi {
    use std::ffi::{c_char, c_void};

    /// Opaque `struct RTCDeviceTy`.
    #[repr(C)]
    pub struct RTCDeviceTy {
        _private: [u8; 0],
    }
    /// Opaque `struct RTCSceneTy`.
    #[repr(C)]
    pub struct RTCSceneTy {
        _private: [u8; 0],
    }
    /// Opaque `struct RTCGeometryTy`.
    #[repr(C)]
    pub struct RTCGeometryTy {
        _private: [u8; 0],
    }
    pub type RTCDevice = *mut RTCDeviceTy;
    pub type RTCScene = *mut RTCSceneTy;
    pub type RTCGeometry = *mut RTCGeometryTy;

    // C enums are passed as (unsigned) int on every platform Embree supports.
    pub type RTCError = u32;
    pub const RTC_ERROR_NONE: RTCError = 0;
    pub const RTC_ERROR_UNKNOWN: RTCError = 1;
    pub const RTC_ERROR_INVALID_ARGUMENT: RTCError = 2;
    pub const RTC_ERROR_INVALID_OPERATION: RTCError = 3;
    pub const RTC_ERROR_OUT_OF_MEMORY: RTCError = 4;
    pub const RTC_ERROR_UNSUPPORTED_CPU: RTCError = 5;
    pub const RTC_ERROR_CANCELLED: RTCError = 6;

    pub type RTCDeviceProperty = u32;
    pub const RTC_DEVICE_PROPERTY_VERSION: RTCDeviceProperty = 0;
    pub const RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED: RTCDeviceProperty = 32;
    pub const RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED: RTCDeviceProperty = 33;
    pub const RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED: RTCDeviceProperty = 34;
    pub const RTC_DEVICE_PROPERTY_RAY_STREAM_SUPPORTED: RTCDeviceProperty = 35;
    pub const RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED: RTCDeviceProperty = 65;

    pub type RTCGeometryType = u32;
    pub const RTC_GEOMETRY_TYPE_TRIANGLE: RTCGeometryType = 0;
    pub const RTC_GEOMETRY_TYPE_INSTANCE: RTCGeometryType = 121;

    pub type RTCBufferType = u32;
    pub const RTC_BUFFER_TYPE_INDEX: RTCBufferType = 0;
    pub const RTC_BUFFER_TYPE_VERTEX: RTCBufferType = 1;

    pub type RTCFormat = u32;
    pub const RTC_FORMAT_UINT3: RTCFormat = 0x5003;
    pub const RTC_FORMAT_FLOAT3: RTCFormat = 0x9003;
    pub const RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR: RTCFormat = 0x9234;

    pub type RTCIntersectContextFlags = u32;
    pub const RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: RTCIntersectContextFlags = 0;
    pub const RTC_INTERSECT_CONTEXT_FLAG_COHERENT: RTCIntersectContextFlags = 1;

    pub const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;
    /// `RTC_MAX_INSTANCE_LEVEL_COUNT` in `rtcore_config.h` of the Debian build.
    pub const RTC_MAX_INSTANCE_LEVEL_COUNT: usize = 1;
    /// `RTC_MAX_TIME_STEP_COUNT` in `rtcore_common.h`: the most keys a geometry may have.
    pub const MAX_TIME_STEPS: usize = 129;

    pub type RTCErrorFunction =
        unsafe extern "C" fn(user_ptr: *mut c_void, code: RTCError, str: *const c_char);
    pub type RTCMemoryMonitorFunction =
        unsafe extern "C" fn(ptr: *mut c_void, bytes: isize, post: bool) -> bool;
    pub type RTCFilterFunctionN = unsafe extern "C" fn(args: *const c_void);

    /// `struct RTCIntersectContext` with `RTC_MAX_INSTANCE_LEVEL_COUNT == 1` and
    /// `RTC_MIN_WIDTH == 0`, which drop `instStackSize` and `minWidthDistanceFactor`.
    #[repr(C)]
    pub struct RTCIntersectContext {
        pub flags: RTCIntersectContextFlags,
        pub filter: Option<RTCFilterFunctionN>,
        pub instID: [u32; RTC_MAX_INSTANCE_LEVEL_COUNT],
    }

    /// `struct RTC_ALIGN(16) RTCRay`.
    #[repr(C, align(16))]
    #[derive(Clone, Copy)]
    pub struct RTCRay {
        pub org_x: f32,
        pub org_y: f32,
        pub org_z: f32,
        pub tnear: f32,
        pub dir_x: f32,
        pub dir_y: f32,
        pub dir_z: f32,
        pub time: f32,
        pub tfar: f32,
        pub mask: u32,
        pub id: u32,
        pub flags: u32,
    }

    /// `struct RTC_ALIGN(16) RTCHit`.
    #[repr(C, align(16))]
    #[derive(Clone, Copy)]
    pub struct RTCHit {
        pub Ng_x: f32,
        pub Ng_y: f32,
        pub Ng_z: f32,
        pub u: f32,
        pub v: f32,
        pub primID: u32,
        pub geomID: u32,
        pub instID: [u32; RTC_MAX_INSTANCE_LEVEL_COUNT],
    }

    /// `struct RTCRayHit`.
    #[repr(C)]
    #[derive(Clone, Copy)]
    pub struct RTCRayHit {
        pub ray: RTCRay,
        pub hit: RTCHit,
    }

    /// `struct RTC_ALIGN(16) RTCPointQuery`: the query point (world space), its time and
    /// radius, which a callback may shrink.
    #[repr(C, align(16))]
    #[derive(Clone, Copy)]
    pub struct RTCPointQuery {
        pub x: f32,
        pub y: f32,
        pub z: f32,
        pub time: f32,
        pub radius: f32,
    }

    /// `struct RTC_ALIGN(16) RTCPointQueryContext` with `RTC_MAX_INSTANCE_LEVEL_COUNT == 1`:
    /// the instance stack (4x4 column-major matrices, undefined while `instStackSize` is 0).
    #[repr(C, align(16))]
    #[derive(Clone, Copy)]
    pub struct RTCPointQueryContext {
        pub world2inst: [[f32; 16]; RTC_MAX_INSTANCE_LEVEL_COUNT],
        pub inst2world: [[f32; 16]; RTC_MAX_INSTANCE_LEVEL_COUNT],
        pub instID: [u32; RTC_MAX_INSTANCE_LEVEL_COUNT],
        pub instStackSize: u32,
    }

    /// `struct RTC_ALIGN(16) RTCPointQueryFunctionArguments`: what a point query callback
    /// is handed for each primitive whose box the query's sphere reaches.
    #[repr(C, align(16))]
    pub struct RTCPointQueryFunctionArguments {
        pub query: *mut RTCPointQuery,
        pub userPtr: *mut c_void,
        pub primID: u32,
        pub geomID: u32,
        pub context: *mut RTCPointQueryContext,
        /// The current instance's world-to-instance scale when it is a similarity (distances
        /// in instance space divided by it are world distances), 0 when it is not, 1 without
        /// an instance.
        pub similarityScale: f32,
    }

    /// `RTCPointQueryFunction`: true when it shrank the query's radius.
    pub type RTCPointQueryFunction =
        unsafe extern "C" fn(args: *mut RTCPointQueryFunctionArguments) -> bool;

    // The layouts the library was compiled with (sizeof in C on x86_64 and aarch64).
    const _: () = assert!(std::mem::size_of::<RTCPointQuery>() == 32);
    const _: () = assert!(std::mem::size_of::<RTCPointQueryContext>() == 144);
    const _: () = assert!(std::mem::align_of::<RTCPointQueryContext>() == 16);
    const _: () = assert!(std::mem::offset_of!(RTCPointQueryContext, instStackSize) == 132);
    const _: () = assert!(std::mem::size_of::<RTCPointQueryFunctionArguments>() == 48);
    const _: () = assert!(std::mem::offset_of!(RTCPointQueryFunctionArguments, context) == 24);
    const _: () =
        assert!(std::mem::offset_of!(RTCPointQueryFunctionArguments, similarityScale) == 32);
    const _: () = assert!(std::mem::size_of::<RTCRay>() == 48);
    const _: () = assert!(std::mem::size_of::<RTCHit>() == 32);
    const _: () = assert!(std::mem::size_of::<RTCRayHit>() == 80);
    const _: () = assert!(std::mem::align_of::<RTCRayHit>() == 16);
    const _: () = assert!(std::mem::size_of::<RTCIntersectContext>() == 24);

    #[link(name = "embree3")]
    extern "C" {
        pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
        pub fn rtcReleaseDevice(device: RTCDevice);
        pub fn rtcGetDeviceProperty(device: RTCDevice, prop: RTCDeviceProperty) -> isize;
        pub fn rtcGetDeviceError(device: RTCDevice) -> RTCError;
        pub fn rtcSetDeviceErrorFunction(
            device: RTCDevice,
            error: Option<RTCErrorFunction>,
            user_ptr: *mut c_void,
        );
        pub fn rtcSetDeviceMemoryMonitorFunction(
            device: RTCDevice,
            monitor: Option<RTCMemoryMonitorFunction>,
            user_ptr: *mut c_void,
        );

        pub fn rtcNewScene(device: RTCDevice) -> RTCScene;
        pub fn rtcReleaseScene(scene: RTCScene);
        pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> u32;
        pub fn rtcCommitScene(scene: RTCScene);

        pub fn rtcNewGeometry(device: RTCDevice, ty: RTCGeometryType) -> RTCGeometry;
        pub fn rtcReleaseGeometry(geometry: RTCGeometry);
        pub fn rtcCommitGeometry(geometry: RTCGeometry);
        pub fn rtcSetGeometryInstancedScene(geometry: RTCGeometry, scene: RTCScene);
        pub fn rtcSetGeometryTransform(
            geometry: RTCGeometry,
            time_step: u32,
            format: RTCFormat,
            xfm: *const c_void,
        );
        pub fn rtcSetGeometryMask(geometry: RTCGeometry, mask: u32);
        pub fn rtcSetGeometryTimeStepCount(geometry: RTCGeometry, time_step_count: u32);
        pub fn rtcSetNewGeometryBuffer(
            geometry: RTCGeometry,
            ty: RTCBufferType,
            slot: u32,
            format: RTCFormat,
            byte_stride: usize,
            item_count: usize,
        ) -> *mut c_void;

        pub fn rtcIntersect1(
            scene: RTCScene,
            context: *mut RTCIntersectContext,
            rayhit: *mut RTCRayHit,
        );
        pub fn rtcOccluded1(scene: RTCScene, context: *mut RTCIntersectContext, ray: *mut RTCRay);
        pub fn rtcIntersect1M(
            scene: RTCScene,
            context: *mut RTCIntersectContext,
            rayhit: *mut RTCRayHit,
            m: u32,
            byte_stride: usize,
        );
        pub fn rtcOccluded1M(
            scene: RTCScene,
            context: *mut RTCIntersectContext,
            ray: *mut RTCRay,
            m: u32,
            byte_stride: usize,
        );
        pub fn rtcPointQuery(
            scene: RTCScene,
            query: *mut RTCPointQuery,
            context: *mut RTCPointQueryContext,
            queryFunc: Option<RTCPointQueryFunction>,
            userPtr: *mut c_void,
        ) -> bool;
    }

    /// `rtcInitIntersectContext`, a `static inline` function in `rtcore_common.h` and so not in
    /// the library.
    pub fn init_intersect_context(flags: RTCIntersectContextFlags) -> RTCIntersectContext {
        RTCIntersectContext {
            flags,
            filter: None,
            instID: [RTC_INVALID_GEOMETRY_ID; RTC_MAX_INSTANCE_LEVEL_COUNT],
        }
    }

    /// `rtcInitPointQueryContext`, `static inline` in `rtcore_common.h`: an empty instance
    /// stack (the header leaves the matrices undefined; zeros here).
    pub fn init_point_query_context() -> RTCPointQueryContext {
        RTCPointQueryContext {
            world2inst: [[0.0; 16]; RTC_MAX_INSTANCE_LEVEL_COUNT],
            inst2world: [[0.0; 16]; RTC_MAX_INSTANCE_LEVEL_COUNT],
            instID: [RTC_INVALID_GEOMETRY_ID; RTC_MAX_INSTANCE_LEVEL_COUNT],
            instStackSize: 0,
        }
    }
}

use ffi::*;

/// Rays per `rtcIntersect1M` / `rtcOccluded1M` call: one 8 × 8 tile of `rays::camera_tiles`,
/// small enough for a stack buffer, larger than Embree's widest packet (16).
const STREAM_CHUNK: usize = 64;

fn error_name(code: RTCError) -> &'static str {
    match code {
        RTC_ERROR_NONE => "RTC_ERROR_NONE",
        RTC_ERROR_UNKNOWN => "RTC_ERROR_UNKNOWN",
        RTC_ERROR_INVALID_ARGUMENT => "RTC_ERROR_INVALID_ARGUMENT",
        RTC_ERROR_INVALID_OPERATION => "RTC_ERROR_INVALID_OPERATION",
        RTC_ERROR_OUT_OF_MEMORY => "RTC_ERROR_OUT_OF_MEMORY",
        RTC_ERROR_UNSUPPORTED_CPU => "RTC_ERROR_UNSUPPORTED_CPU",
        RTC_ERROR_CANCELLED => "RTC_ERROR_CANCELLED",
        _ => "unknown RTCError",
    }
}

/// Embree reports the message only through the error callback (the code alone through
/// `rtcGetDeviceError`); keep the latest one for the `Err` we return. Called on whatever thread
/// hit the error (TBB build threads too), hence the mutex; must not unwind into C.
unsafe extern "C" fn record_error(user_ptr: *mut c_void, code: RTCError, message: *const c_char) {
    let Some(slot) = (user_ptr as *const Mutex<Option<String>>).as_ref() else {
        return;
    };
    let text = if message.is_null() {
        String::new()
    } else {
        CStr::from_ptr(message).to_string_lossy().into_owned()
    };
    if let Ok(mut last) = slot.lock() {
        *last = Some(format!("{} ({code}): {text}", error_name(code)));
    }
}

/// Embree's memory monitor: adds every allocation (positive) and release (negative) of the
/// device to the counter, and never refuses one. Called on Embree's build threads too, hence
/// the atomic; must not unwind into C.
unsafe extern "C" fn count_memory(user_ptr: *mut c_void, bytes: isize, _post: bool) -> bool {
    if let Some(counter) = (user_ptr as *const AtomicI64).as_ref() {
        counter.fetch_add(bytes as i64, Ordering::Relaxed);
    }
    true
}

/// The device, the error slot its callback writes to and the byte count its memory monitor
/// keeps: both must outlive the device, and scenes keep the device alive, so all live behind
/// one `Arc`.
/// What went wrong in Embree or its bridge: the call (or step) and what Embree said.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EmbreeError {
    /// The Embree call or bridge step that failed.
    pub call: String,
    /// Embree's message (its error name and code where it gave no message), or the bridge's.
    pub message: String,
}

impl EmbreeError {
    fn new(call: &str, message: impl Into<String>) -> EmbreeError {
        EmbreeError {
            call: call.to_string(),
            message: message.into(),
        }
    }
}

impl std::fmt::Display for EmbreeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Embree: {}: {}", self.call, self.message)
    }
}

impl std::error::Error for EmbreeError {}

struct Device {
    raw: RTCDevice,
    last_error: Box<Mutex<Option<String>>>,
    memory: Box<AtomicI64>,
}

// SAFETY: Embree's API is thread-safe for creating and committing different scenes on one
// device; the only Rust-side state is the mutex-guarded error slot.
unsafe impl Send for Device {}
unsafe impl Sync for Device {}

impl Device {
    /// `Err` with Embree's code and message if anything failed since the last check.
    fn check(&self, what: &str) -> Result<(), EmbreeError> {
        let code = unsafe { rtcGetDeviceError(self.raw) };
        let message = self.last_error.lock().ok().and_then(|mut m| m.take());
        match (code, message) {
            (RTC_ERROR_NONE, None) => Ok(()),
            (_, Some(m)) => Err(EmbreeError::new(what, m)),
            (code, None) => Err(EmbreeError::new(
                what,
                format!("{} ({code})", error_name(code)),
            )),
        }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // Runs after the last scene is released (each holds an `Arc<Device>`), so this destroys
        // the device before its error slot drops: no callback can reach a freed slot.
        unsafe { rtcReleaseDevice(self.raw) }
    }
}

/// An Embree device: the factory of scenes and the owner of Embree's build threads (its own
/// TBB pool, not rayon's; queries run on the calling thread).
#[derive(Clone)]
pub struct EmbreeDevice {
    inner: Arc<Device>,
}

impl EmbreeDevice {
    /// A device with Embree's default configuration: builds use all hardware threads.
    pub fn new() -> Result<Self, EmbreeError> {
        Self::with_config(None)
    }

    /// A device whose builds use `threads` threads (`threads=N` in Embree's configuration
    /// string; 0 means all hardware threads). Embree's TBB scheduler is process-wide and takes
    /// the largest count of all live devices, so a 1-thread build only runs on 1 thread while
    /// no device with more threads exists.
    pub fn with_threads(threads: usize) -> Result<Self, EmbreeError> {
        Self::with_config(Some(&format!("threads={threads}")))
    }

    /// The device for `config` (Embree's configuration string), with whatever
    /// `QUIVER_EMBREE_CONFIG` holds appended: e.g. `isa=avx2` to run Embree's AVX2 kernels on
    /// a CPU where it would pick its AVX-512 ones (as quiver has none), which README's
    /// comparisons name where they use it.
    fn with_config(config: Option<&str>) -> Result<Self, EmbreeError> {
        let extra = std::env::var("QUIVER_EMBREE_CONFIG").ok();
        let config = match (config, extra.as_deref()) {
            (Some(c), Some(e)) => Some(format!("{c},{e}")),
            (c, e) => c.or(e).map(str::to_owned),
        };
        let config = config
            .map(CString::new)
            .transpose()
            .map_err(|e| EmbreeError::new("configuration string", e.to_string()))?;
        let config_ptr = config.as_ref().map_or(std::ptr::null(), |c| c.as_ptr());
        let raw = unsafe { rtcNewDevice(config_ptr) };
        if raw.is_null() {
            // Without a device there is no callback and no message, only the code.
            let code = unsafe { rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(EmbreeError::new(
                "rtcNewDevice",
                format!("failed: {} ({code})", error_name(code)),
            ));
        }
        let device = Device {
            raw,
            last_error: Box::new(Mutex::new(None)),
            memory: Box::new(AtomicI64::new(0)),
        };
        let slot: *const Mutex<Option<String>> = &*device.last_error;
        unsafe { rtcSetDeviceErrorFunction(raw, Some(record_error), slot as *mut c_void) };
        let counter: *const AtomicI64 = &*device.memory;
        unsafe {
            rtcSetDeviceMemoryMonitorFunction(raw, Some(count_memory), counter as *mut c_void)
        };
        device.check("rtcNewDevice")?;
        // Culling back faces would answer a different question than quiver's two-sided test.
        let culling = RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED;
        if unsafe { rtcGetDeviceProperty(raw, culling) } != 0 {
            return Err(EmbreeError::new(
                "rtcGetDeviceProperty",
                "this libembree3 culls back faces; quiver's are two-sided",
            ));
        }
        Ok(EmbreeDevice {
            inner: Arc::new(device),
        })
    }

    /// Embree's version as `major.minor.patch`.
    pub fn version(&self) -> String {
        let v = unsafe { rtcGetDeviceProperty(self.inner.raw, RTC_DEVICE_PROPERTY_VERSION) };
        format!("{}.{}.{}", v / 10000, v / 100 % 100, v % 100)
    }

    /// The widest instruction set this device's kernels run on, as its native packet widths
    /// show: Embree enables `rtcIntersect16` only when it selected its AVX-512 kernels (on this
    /// CPU and not forced lower by `isa=` in the configuration), 8 for AVX or AVX2, 4 for SSE.
    /// E.g. `"avx512"`, `"avx2"` (with `QUIVER_EMBREE_CONFIG=isa=avx2`).
    pub fn isa(&self) -> &'static str {
        let native = |p| unsafe { rtcGetDeviceProperty(self.inner.raw, p) != 0 };
        if native(RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) {
            "avx512"
        } else if native(RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) {
            // Embree's AVX-only target exists, but on a CPU with AVX2 it takes AVX2.
            #[cfg(target_arch = "x86_64")]
            let avx2 = std::arch::is_x86_feature_detected!("avx2");
            #[cfg(not(target_arch = "x86_64"))]
            let avx2 = false;
            if avx2 {
                "avx2"
            } else {
                "avx"
            }
        } else if native(RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED) {
            "sse"
        } else {
            "scalar"
        }
    }

    /// Whether this library was built with ray streams (`rtcIntersect1M`); without them the
    /// stream forms of [`EmbreeScene`] fall back to one ray at a time.
    pub fn ray_streams(&self) -> bool {
        let p = RTC_DEVICE_PROPERTY_RAY_STREAM_SUPPORTED;
        unsafe { rtcGetDeviceProperty(self.inner.raw, p) != 0 }
    }
}

/// One committed Embree scene holding one triangle mesh (primitive IDs are indices into the
/// slice it was built from, as in quiver), or instances of such scenes
/// ([`EmbreeScene::instanced`]).
pub struct EmbreeScene {
    raw: RTCScene,
    streams: bool,
    /// What the device's memory monitor counted across `rtcCommitScene` (of this scene and,
    /// for an instanced one, of the scenes it places).
    bvh_bytes: i64,
    /// The scenes an instanced scene places, kept alive as long as it.
    placed: Vec<EmbreeScene>,
    /// A triangle scene's triangles (at its first time step), which its point queries
    /// measure; empty for an instanced scene.
    tris: Vec<Triangle>,
    /// An instanced scene's instances (by Embree's geometry ID, their order): the index in
    /// `placed` of the scene each places.
    instance_scene: Vec<u32>,
    /// Keeps the device (and its error slot) alive as long as the scene.
    _device: Arc<Device>,
}

// SAFETY: after `rtcCommitScene` an Embree scene may be queried from any number of threads at
// once; `EmbreeScene` exposes no way to modify it.
unsafe impl Send for EmbreeScene {}
unsafe impl Sync for EmbreeScene {}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // Before `_device` drops, so the device's last release comes after the scene's.
        unsafe { rtcReleaseScene(self.raw) }
    }
}

impl EmbreeScene {
    /// Builds over `tris` on a new default device (all hardware threads for the build).
    pub fn new(tris: &[Triangle]) -> Result<Self, EmbreeError> {
        Self::on_device(&EmbreeDevice::new()?, tris)
    }

    /// Builds over `tris` on `device`: one triangle geometry (a `FLOAT3` vertex buffer with
    /// three vertices per triangle and a `UINT3` index buffer), Embree's default build quality
    /// (medium) and scene flags, committed. Triangles with non-finite vertices are skipped by
    /// Embree as by quiver.
    pub fn on_device(device: &EmbreeDevice, tris: &[Triangle]) -> Result<Self, EmbreeError> {
        Self::deforming_on_device(device, &[tris])
    }

    /// [`EmbreeScene::on_device`] over a deforming mesh: `steps` holds its triangles at
    /// evenly spaced times over the shutter [0, 1], the same triangles in the same order at
    /// every step (`rtcSetGeometryTimeStepCount`, one vertex buffer slot a step; Embree
    /// interpolates the vertices linearly, as quiver's moving meshes do). One step is a
    /// static mesh.
    ///
    /// ```
    /// use glam::Vec3A;
    /// use quiver_rt::{Ray, Triangle};
    /// use quiver_lab::embree::{EmbreeDevice, EmbreeScene};
    /// let near = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let far = Triangle::new(-2.0 * Vec3A::Z, Vec3A::X - 2.0 * Vec3A::Z, Vec3A::Y - 2.0 * Vec3A::Z);
    /// let scene = EmbreeScene::deforming_on_device(&EmbreeDevice::new().unwrap(), &[&[near], &[far]]).unwrap();
    /// let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
    /// assert_eq!(scene.closest_hit(&ray.with_time(0.5)), Some((0, 2.0)));
    /// ```
    pub fn deforming_on_device(
        device: &EmbreeDevice,
        steps: &[&[Triangle]],
    ) -> Result<Self, EmbreeError> {
        let dev = &device.inner;
        let tris = steps.first().copied().unwrap_or(&[]);
        if steps.len() > MAX_TIME_STEPS || steps.iter().any(|s| s.len() != tris.len()) {
            return Err(EmbreeError::new(
                "time steps",
                format!(
                    "{} steps (Embree takes 1 to {MAX_TIME_STEPS}, each of as many triangles)",
                    steps.len()
                ),
            ));
        }
        let vertices = tris
            .len()
            .checked_mul(3)
            .filter(|&n| n <= u32::MAX as usize);
        let Some(vertices) = vertices else {
            return Err(EmbreeError::new(
                "vertex buffer",
                format!("{} triangles exceed 32-bit vertex indices", tris.len()),
            ));
        };
        let raw = unsafe { rtcNewScene(dev.raw) };
        if raw.is_null() {
            dev.check("rtcNewScene")?;
            return Err(EmbreeError::new("rtcNewScene", "returned no scene"));
        }
        // From here on, an early return releases the scene.
        let mut scene = EmbreeScene {
            raw,
            streams: device.ray_streams(),
            bvh_bytes: 0,
            placed: Vec::new(),
            tris: tris.to_vec(),
            instance_scene: Vec::new(),
            _device: dev.clone(),
        };
        // An empty scene is one without geometry, rather than one with zero-sized buffers.
        if !tris.is_empty() {
            let geom = unsafe { rtcNewGeometry(dev.raw, RTC_GEOMETRY_TYPE_TRIANGLE) };
            if geom.is_null() {
                dev.check("rtcNewGeometry")?;
                return Err(EmbreeError::new("rtcNewGeometry", "returned no geometry"));
            }
            if steps.len() > 1 {
                // SAFETY: `geom` is a new triangle geometry of this device, the count within
                // Embree's limit (checked above), set before any buffer.
                unsafe { rtcSetGeometryTimeStepCount(geom, steps.len() as u32) };
            }
            let filled = fill_buffers(dev, geom, steps, vertices);
            if filled.is_ok() {
                unsafe {
                    rtcCommitGeometry(geom);
                    rtcAttachGeometry(raw, geom);
                }
            }
            // The scene holds its own reference once attached.
            unsafe { rtcReleaseGeometry(geom) };
            filled?;
            dev.check("rtcCommitGeometry / rtcAttachGeometry")?;
        }
        let before = dev.memory.load(Ordering::Relaxed);
        unsafe { rtcCommitScene(raw) };
        scene.bvh_bytes = dev.memory.load(Ordering::Relaxed) - before;
        dev.check("rtcCommitScene")?;
        Ok(scene)
    }

    /// Instances (`RTC_GEOMETRY_TYPE_INSTANCE`) of one committed scene per geometry, each
    /// placed by its object-to-world transform (`FLOAT3X4_COLUMN_MAJOR`) with its mask: the
    /// scene quiver's `World` traces, as Embree builds it (a top-level BVH over the
    /// instances, each geometry's BVH once). Hits report the geometry's primitive.
    ///
    /// ```
    /// use glam::{Affine3A, Vec3, Vec3A};
    /// use quiver_rt::{Ray, Triangle};
    /// use quiver_lab::embree::{EmbreeDevice, EmbreeScene};
    /// let tri = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
    /// let far = Affine3A::from_translation(Vec3::new(0.0, 0.0, -2.0));
    /// let scene = EmbreeScene::instanced(&EmbreeDevice::new().unwrap(), &[tri], &[(0, Affine3A::IDENTITY, 1), (0, far, 2)]).unwrap();
    /// let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
    /// assert_eq!(scene.closest_hit(&ray), Some((0, 1.0)));
    /// ```
    pub fn instanced(
        device: &EmbreeDevice,
        geometries: &[Vec<Triangle>],
        instances: &[(u32, glam::Affine3A, u32)],
    ) -> Result<Self, EmbreeError> {
        let keyed: Vec<(u32, &[glam::Affine3A], u32)> = instances
            .iter()
            .map(|(g, m, mask)| (*g, std::slice::from_ref(m), *mask))
            .collect();
        Self::instanced_moving(device, geometries, &keyed)
    }

    /// [`EmbreeScene::instanced`] with each instance placed by its keys, evenly spaced over
    /// the shutter [0, 1] (`rtcSetGeometryTimeStepCount`, one `rtcSetGeometryTransform` a
    /// step; Embree interpolates the matrices linearly, as quiver's
    /// `Interpolation::Linear` does): motion-blurred instances met at each ray's `time`.
    /// One key is a static instance.
    ///
    /// ```
    /// use glam::{Affine3A, Vec3, Vec3A};
    /// use quiver_rt::{Ray, Triangle};
    /// use quiver_lab::embree::{EmbreeDevice, EmbreeScene};
    /// let tri = vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)];
    /// let keys = [Affine3A::IDENTITY, Affine3A::from_translation(Vec3::new(0.0, 0.0, -2.0))];
    /// let scene = EmbreeScene::instanced_moving(&EmbreeDevice::new().unwrap(), &[tri], &[(0, &keys[..], 1)]).unwrap();
    /// let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
    /// assert_eq!(scene.closest_hit(&ray.with_time(0.5)), Some((0, 2.0)));
    /// ```
    pub fn instanced_moving(
        device: &EmbreeDevice,
        geometries: &[Vec<Triangle>],
        instances: &[(u32, &[glam::Affine3A], u32)],
    ) -> Result<Self, EmbreeError> {
        let steps: Vec<[&[Triangle]; 1]> = geometries.iter().map(|g| [&g[..]]).collect();
        let steps: Vec<&[&[Triangle]]> = steps.iter().map(|s| &s[..]).collect();
        Self::instanced_deforming(device, &steps, instances)
    }

    /// Embree's scene of a quiver `World`: its geometries (a moving mesh at its first step,
    /// Embree being given no deforming geometry here) and instances with their masks, a moving
    /// instance with its motion's keys as Embree's time steps (as linear motions
    /// interpolate them), by [`EmbreeScene::instanced_moving`]. Instance `i` of the world is
    /// instance `i` of the scene.
    pub fn of_world(device: &EmbreeDevice, world: &quiver_rt::World) -> Result<Self, EmbreeError> {
        let (geometries, keys) = world_parts(world);
        Self::instanced_moving(device, &geometries, &placements(world, &keys))
    }

    /// [`EmbreeScene::of_world`] for [`EmbreeScene::closest_point`] on Embree 3.13, whose
    /// instanced point queries are wrong under a similarity that shrinks (an instance scaled
    /// by `s < 1`): in instance space its node test culls with the world radius where the
    /// radius times `1/s` is needed (`PointQueryContext::query_radius` is not scaled by
    /// `similarityScale`; Embree 4 scales it), so nearer triangles are missed. Here each
    /// geometry is stored shrunk by a power of two `k` and its instances enlarged by `k`
    /// (exact in f32: the placed vertices are the same bits), `k` the least that leaves no
    /// instance of it scaled below 1; Embree's culling is then conservative (a larger radius
    /// than needed in instances scaled above 1), so the answers are right and its speed is
    /// Embree's own traversal paying that slack. Instance and triangle numbers are
    /// [`EmbreeScene::of_world`]'s.
    pub fn of_world_for_points(
        device: &EmbreeDevice,
        world: &quiver_rt::World,
    ) -> Result<Self, EmbreeError> {
        let (mut geometries, mut keys) = world_parts(world);
        for (g, tris) in geometries.iter_mut().enumerate() {
            let smallest = world
                .instances()
                .iter()
                .zip(&keys)
                .filter(|(i, _)| i.geometry.0 as usize == g)
                .flat_map(|(_, k)| k.iter())
                .map(|m| {
                    let c = &m.matrix3;
                    c.x_axis
                        .length()
                        .min(c.y_axis.length())
                        .min(c.z_axis.length())
                })
                .fold(f32::INFINITY, f32::min);
            if !(smallest > 0.0 && smallest < 1.0) {
                continue;
            }
            let k = 2f32.powi((1.0 / smallest).log2().ceil() as i32);
            for t in tris.iter_mut() {
                t.v = t.v.map(|v| v / k);
            }
            for (i, ks) in world.instances().iter().zip(keys.iter_mut()) {
                if i.geometry.0 as usize == g {
                    for m in ks.iter_mut() {
                        m.matrix3 *= k;
                    }
                }
            }
        }
        Self::instanced_moving(device, &geometries, &placements(world, &keys))
    }

    /// [`EmbreeScene::instanced_moving`] over geometries that may deform: geometry `g` is
    /// `geometries[g]`'s time steps, as [`EmbreeScene::deforming_on_device`] takes them.
    pub fn instanced_deforming(
        device: &EmbreeDevice,
        geometries: &[&[&[Triangle]]],
        instances: &[(u32, &[glam::Affine3A], u32)],
    ) -> Result<Self, EmbreeError> {
        let dev = &device.inner;
        let before = dev.memory.load(Ordering::Relaxed);
        let placed = geometries
            .iter()
            .map(|g| EmbreeScene::deforming_on_device(device, g))
            .collect::<Result<Vec<_>, _>>()?;
        let raw = unsafe { rtcNewScene(dev.raw) };
        if raw.is_null() {
            dev.check("rtcNewScene")?;
            return Err(EmbreeError::new("rtcNewScene", "returned no scene"));
        }
        let mut scene = EmbreeScene {
            raw,
            streams: device.ray_streams(),
            bvh_bytes: 0,
            placed,
            tris: Vec::new(),
            instance_scene: Vec::with_capacity(instances.len()),
            _device: dev.clone(),
        };
        for &(g, keys, mask) in instances {
            let Some(child) = scene.placed.get(g as usize) else {
                return Err(EmbreeError::new(
                    "instances",
                    format!("an instance of geometry {g} of {}", geometries.len()),
                ));
            };
            let geom = unsafe { rtcNewGeometry(dev.raw, RTC_GEOMETRY_TYPE_INSTANCE) };
            if geom.is_null() {
                dev.check("rtcNewGeometry (instance)")?;
                return Err(EmbreeError::new("rtcNewGeometry", "returned no geometry"));
            }
            if keys.is_empty() || keys.len() > MAX_TIME_STEPS {
                // SAFETY: `geom` is a geometry of this device, released once.
                unsafe { rtcReleaseGeometry(geom) };
                return Err(EmbreeError::new(
                    "instances",
                    format!("{} keys (Embree takes 1 to {MAX_TIME_STEPS})", keys.len()),
                ));
            }
            // SAFETY: `geom` is a new instance geometry of this device, `child.raw` a
            // committed scene of it that `scene.placed` keeps alive, the step count within
            // Embree's limit (checked above), and each transform twelve floats in the
            // column-major 3x4 layout the format names (Embree copies them).
            unsafe {
                rtcSetGeometryInstancedScene(geom, child.raw);
                if keys.len() > 1 {
                    rtcSetGeometryTimeStepCount(geom, keys.len() as u32);
                }
                for (step, m) in keys.iter().enumerate() {
                    let cols = [
                        m.matrix3.x_axis,
                        m.matrix3.y_axis,
                        m.matrix3.z_axis,
                        m.translation,
                    ];
                    let xfm: [f32; 12] = std::array::from_fn(|k| cols[k / 3][k % 3]);
                    rtcSetGeometryTransform(
                        geom,
                        step as u32,
                        RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR,
                        xfm.as_ptr().cast(),
                    );
                }
                rtcSetGeometryMask(geom, mask);
                rtcCommitGeometry(geom);
            }
            // SAFETY: `geom` is a committed geometry of this device, attached to the scene
            // (which keeps its own reference) and released once.
            let id = unsafe {
                let id = rtcAttachGeometry(raw, geom);
                rtcReleaseGeometry(geom);
                id
            };
            dev.check("instance geometry")?;
            // A new scene numbers its geometries in attach order; point queries rely on it.
            if id as usize != scene.instance_scene.len() {
                return Err(EmbreeError::new(
                    "rtcAttachGeometry",
                    format!(
                        "instance {} got geometry ID {id}",
                        scene.instance_scene.len()
                    ),
                ));
            }
            scene.instance_scene.push(g);
        }
        unsafe { rtcCommitScene(raw) };
        scene.bvh_bytes = dev.memory.load(Ordering::Relaxed) - before;
        dev.check("rtcCommitScene (instances)")?;
        Ok(scene)
    }

    /// Bytes Embree allocated while committing the scene and still holds, by its device
    /// memory monitor (`rtcSetDeviceMemoryMonitorFunction`): its BVH, nodes and triangle
    /// leaves (Triangle4: vertices copied in), without the vertex and index buffers set
    /// before the commit, which the traversal does not read. Exact only while no other scene
    /// of the same device is built at the same time.
    pub fn bvh_bytes(&self) -> usize {
        self.bvh_bytes.max(0) as usize
    }

    /// The nearest hit within `[ray.t_min, ray.t_max]` (`rtcIntersect1`) as (triangle index,
    /// t); the tie between triangles at equal t is Embree's, not quiver's lowest index.
    #[inline]
    pub fn closest_hit(&self, ray: &Ray) -> Option<(u32, f32)> {
        let mut rh = ray_hit(ray);
        let mut ctx = init_intersect_context(RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        unsafe { rtcIntersect1(self.raw, &mut ctx, &mut rh) };
        hit_of(&rh)
    }

    /// Whether anything lies within `[ray.t_min, ray.t_max]` (`rtcOccluded1`).
    #[inline]
    pub fn any_hit(&self, ray: &Ray) -> bool {
        let mut r = rtc_ray(ray);
        let mut ctx = init_intersect_context(RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        unsafe { rtcOccluded1(self.raw, &mut ctx, &mut r) };
        occluded(&r)
    }

    /// The point of the scene's triangles nearest `point` within `max_distance` (inclusive),
    /// by `rtcPointQuery` with a callback that measures each triangle Embree offers by
    /// quiver's own [`Triangle::closest_point`] (on the bridge's copy of the triangles, so
    /// the per-primitive work is quiver's) and shrinks the query's radius to the best
    /// distance. `None` when nothing lies that near, or for a NaN or non-finite point or a
    /// NaN or negative distance.
    ///
    /// Distances are world-space, as `World::closest_point`'s: in an instanced scene a
    /// triangle under a similarity transform (Embree's `similarityScale` > 0) is measured in
    /// instance space from the point brought in by Embree's world-to-instance matrix and the
    /// distance divided by the scale; under any other transform it is placed in world space
    /// by Embree's instance-to-world matrix and measured there (as Embree's `closest_point`
    /// tutorial does). Equal distances go to the lower instance, then the lower triangle, as
    /// in quiver, among the triangles Embree offers. A deforming scene is measured at its
    /// first step and moving instances at their first key (time 0).
    ///
    /// ```
    /// use glam::{Affine3A, Vec3, Vec3A};
    /// use quiver_rt::Triangle;
    /// use quiver_lab::embree::{EmbreeDevice, EmbreePointHit, EmbreeScene};
    /// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let scene = EmbreeScene::new(&[tri]).unwrap();
    /// let hit = scene.closest_point(Vec3A::new(0.25, 0.5, 2.0), f32::INFINITY).unwrap();
    /// assert_eq!(hit, EmbreePointHit { prim: 0, instance: None, point: Vec3A::new(0.25, 0.5, 0.0), distance: 2.0 });
    /// assert_eq!(scene.closest_point(Vec3A::new(0.25, 0.5, 2.0), 1.5), None);
    /// // Instances: one stretched four times along x (not a similarity), one raised by 5.
    /// let stretch = Affine3A::from_scale(Vec3::new(4.0, 1.0, 1.0));
    /// let up = Affine3A::from_translation(Vec3::new(0.0, 0.0, 5.0));
    /// let world = EmbreeScene::instanced(&EmbreeDevice::new().unwrap(), &[vec![tri]], &[(0, stretch, 1), (0, up, 1)]).unwrap();
    /// let hit = world.closest_point(Vec3A::new(2.0, 0.25, 1.5), f32::INFINITY).unwrap();
    /// assert_eq!((hit.instance, hit.point, hit.distance), (Some(0), Vec3A::new(2.0, 0.25, 0.0), 1.5));
    /// let hit = world.closest_point(Vec3A::new(0.2, 0.2, 4.0), f32::INFINITY).unwrap();
    /// assert_eq!((hit.instance, hit.distance), (Some(1), 1.0));
    /// ```
    pub fn closest_point(&self, point: Vec3A, max_distance: f32) -> Option<EmbreePointHit> {
        if !(point.is_finite() && max_distance >= 0.0) {
            return None;
        }
        let mut query = RTCPointQuery {
            x: point.x,
            y: point.y,
            z: point.z,
            time: 0.0,
            radius: max_distance,
        };
        let mut ctx = init_point_query_context();
        let mut search = PointSearch {
            scene: self,
            point,
            limit: max_distance as f64,
            best: None,
        };
        // SAFETY: the scene is committed and alive; `query` and `ctx` are initialized and
        // aligned as Embree's structs; `search` outlives the call, and the callback reads it
        // (and the scene, through it) only during the call, on this thread.
        unsafe {
            rtcPointQuery(
                self.raw,
                &mut query,
                &mut ctx,
                Some(closest_point_callback),
                (&mut search as *mut PointSearch).cast(),
            );
        }
        search.best.map(|(_, hit)| hit)
    }

    /// [`closest_hit`](Self::closest_hit) for every ray, handed to Embree as coherent streams
    /// (`rtcIntersect1M`, `RTC_INTERSECT_CONTEXT_FLAG_COHERENT`) of up to 64 consecutive rays,
    /// so Embree may trace them as packets: give it packet-ordered rays (e.g.
    /// `rays::camera_tiles`). The answers are the single-ray form's.
    ///
    /// # Panics
    /// If `out` and `rays` differ in length.
    pub fn closest_hit_stream(&self, rays: &[Ray], out: &mut [Option<(u32, f32)>]) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        if !self.streams {
            for (r, o) in rays.iter().zip(out) {
                *o = self.closest_hit(r);
            }
            return;
        }
        let mut buf = [const { MaybeUninit::<RTCRayHit>::uninit() }; STREAM_CHUNK];
        for (rays, out) in rays.chunks(STREAM_CHUNK).zip(out.chunks_mut(STREAM_CHUNK)) {
            for (b, r) in buf.iter_mut().zip(rays) {
                b.write(ray_hit(r));
            }
            let mut ctx = init_intersect_context(RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
            unsafe {
                rtcIntersect1M(
                    self.raw,
                    &mut ctx,
                    buf.as_mut_ptr().cast(),
                    rays.len() as u32,
                    std::mem::size_of::<RTCRayHit>(),
                );
            }
            for (o, b) in out.iter_mut().zip(&buf) {
                // SAFETY: the first `rays.len()` entries were written above.
                *o = hit_of(unsafe { b.assume_init_ref() });
            }
        }
    }

    /// [`any_hit`](Self::any_hit) for every ray as coherent streams (`rtcOccluded1M`), as
    /// [`closest_hit_stream`](Self::closest_hit_stream).
    ///
    /// # Panics
    /// If `out` and `rays` differ in length.
    pub fn any_hit_stream(&self, rays: &[Ray], out: &mut [bool]) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        if !self.streams {
            for (r, o) in rays.iter().zip(out) {
                *o = self.any_hit(r);
            }
            return;
        }
        let mut buf = [const { MaybeUninit::<RTCRay>::uninit() }; STREAM_CHUNK];
        for (rays, out) in rays.chunks(STREAM_CHUNK).zip(out.chunks_mut(STREAM_CHUNK)) {
            for (b, r) in buf.iter_mut().zip(rays) {
                b.write(rtc_ray(r));
            }
            let mut ctx = init_intersect_context(RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
            unsafe {
                rtcOccluded1M(
                    self.raw,
                    &mut ctx,
                    buf.as_mut_ptr().cast(),
                    rays.len() as u32,
                    std::mem::size_of::<RTCRay>(),
                );
            }
            for (o, b) in out.iter_mut().zip(&buf) {
                // SAFETY: the first `rays.len()` entries were written above.
                *o = occluded(unsafe { b.assume_init_ref() });
            }
        }
    }

    /// How many of `rays` hit (closest hit, or any hit with `any`), traced on the current
    /// thread pool one at a time (`stream: false`) or as coherent streams, in the tasks the
    /// other engines' timed loops use ([`crate::measure::count_hits`]).
    pub fn count_hits(&self, rays: &[Ray], any: bool, stream: bool) -> usize {
        use rayon::prelude::*;
        rays.par_chunks(crate::measure::RAYS_PER_TASK)
            .map(|chunk| match (any, stream) {
                (false, false) => chunk
                    .iter()
                    .filter(|r| self.closest_hit(r).is_some())
                    .count(),
                (true, false) => chunk.iter().filter(|r| self.any_hit(r)).count(),
                (false, true) => {
                    let mut hits = vec![None; chunk.len()];
                    self.closest_hit_stream(chunk, &mut hits);
                    hits.iter().filter(|h| h.is_some()).count()
                }
                (true, true) => {
                    let mut hit = vec![false; chunk.len()];
                    self.any_hit_stream(chunk, &mut hit);
                    hit.iter().filter(|&&h| h).count()
                }
            })
            .sum()
    }
}

/// A world's geometries (a moving mesh at its first step) and each instance's keys (one for
/// a static instance), as [`EmbreeScene::of_world`] gives them to Embree.
fn world_parts(world: &quiver_rt::World) -> (Vec<Vec<Triangle>>, Vec<Vec<Affine3A>>) {
    use quiver_rt::world::Geometry;
    let geometries = world
        .geometries()
        .iter()
        .map(|g| match g {
            Geometry::Triangles(_, t) => t.clone(),
            Geometry::Prims(_, t) => t.clone(),
            Geometry::MovingTriangles(m) => m.steps()[0].clone(),
        })
        .collect();
    let keys = world
        .instances()
        .iter()
        .enumerate()
        .map(
            |(id, i)| match world.motion(quiver_rt::InstanceId(id as u32)) {
                Some(m) => m.keys().to_vec(),
                None => vec![i.transform],
            },
        )
        .collect();
    (geometries, keys)
}

/// The world's instances as [`EmbreeScene::instanced_moving`] takes them, with `keys`.
fn placements<'a>(
    world: &quiver_rt::World,
    keys: &'a [Vec<Affine3A>],
) -> Vec<(u32, &'a [Affine3A], u32)> {
    world
        .instances()
        .iter()
        .zip(keys)
        .map(|(i, k)| (i.geometry.0, k.as_slice(), i.mask))
        .collect()
}

/// The closest point of an [`EmbreeScene`]'s triangles ([`EmbreeScene::closest_point`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmbreePointHit {
    /// The triangle: its index in the scene's (or the instanced geometry's) triangles.
    pub prim: u32,
    /// The instance (its index in the instances given) in an instanced scene.
    pub instance: Option<u32>,
    /// The nearest point, in world space.
    pub point: Vec3A,
    /// The world-space distance from the query point to `point`.
    pub distance: f32,
}

/// A closest-point query under way: what [`closest_point_callback`] reads and updates.
struct PointSearch<'a> {
    scene: &'a EmbreeScene,
    /// The query point, world space.
    point: Vec3A,
    /// The largest distance still accepted (the best so far, or the caller's limit).
    limit: f64,
    /// The best so far: its (instance, triangle) for ties, and the answer.
    best: Option<((u32, u32), EmbreePointHit)>,
}

/// A column-major 4x4 matrix of Embree's instance stack as an affine map.
fn affine_of(m: &[f32; 16]) -> Affine3A {
    Affine3A::from_cols_array(&[
        m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10], m[12], m[13], m[14],
    ])
}

impl PointSearch<'_> {
    /// Measures triangle `prim` of the scene the query is in (the top scene, or the one
    /// the instance on `ctx`'s stack places); true when it became the best (and the radius
    /// shrank). Never panics: what it cannot find it skips.
    fn offer(
        &mut self,
        prim: u32,
        ctx: Option<&RTCPointQueryContext>,
        similarity: f32,
        query: &mut RTCPointQuery,
    ) -> bool {
        let scene = self.scene;
        let instanced = ctx.filter(|c| c.instStackSize > 0);
        let (tris, instance) = match instanced {
            None => (&scene.tris, None),
            Some(c) => {
                let inst = c.instID[0];
                let placed = scene
                    .instance_scene
                    .get(inst as usize)
                    .and_then(|&g| scene.placed.get(g as usize));
                match placed {
                    Some(s) => (&s.tris, Some(inst)),
                    None => return false,
                }
            }
        };
        let Some(&tri) = tris.get(prim as usize) else {
            return false;
        };
        let p = self.point;
        let (point, d) = match instanced {
            None => {
                let (q, _, _) = tri.closest_point(p);
                (q, (wide(p) - wide(q)).length())
            }
            Some(c) if similarity > 0.0 => {
                // Measured in instance space and scaled back to world units.
                let local = affine_of(&c.world2inst[0]).transform_point3a(p);
                let (q, _, _) = tri.closest_point(local);
                let d = (wide(local) - wide(q)).length() / similarity as f64;
                (affine_of(&c.inst2world[0]).transform_point3a(q), d)
            }
            Some(c) => {
                // Not a similarity: the triangle placed in world space and measured there.
                let m = affine_of(&c.inst2world[0]);
                let placed = Triangle {
                    v: tri.v.map(|v| m.transform_point3a(v)),
                };
                let (q, _, _) = placed.closest_point(p);
                (q, (wide(p) - wide(q)).length())
            }
        };
        let key = (instance.unwrap_or(0), prim);
        let better = match &self.best {
            None => d <= self.limit,
            Some((k, _)) => d < self.limit || (d == self.limit && key < *k),
        };
        if !better {
            return false;
        }
        self.limit = d;
        let hit = EmbreePointHit {
            prim,
            instance,
            point,
            distance: d as f32,
        };
        self.best = Some((key, hit));
        // Embree's radius in f32, rounded up so that it never prunes a box at distance `d`.
        let mut r = d as f32;
        if (r as f64) < d {
            r = r.next_up();
        }
        let shrank = r < query.radius;
        query.radius = query.radius.min(r);
        shrank
    }
}

/// The `RTCPointQueryFunction` of [`EmbreeScene::closest_point`]: measures the primitive
/// Embree offers and shrinks the radius. Must not unwind into C: [`PointSearch::offer`]
/// cannot panic, and null pointers are skipped.
unsafe extern "C" fn closest_point_callback(args: *mut RTCPointQueryFunctionArguments) -> bool {
    // SAFETY: Embree hands a valid argument struct for the duration of the call (or null,
    // skipped); its `query` is the caller's `RTCPointQuery` and its `context` the caller's
    // context, both live for the whole `rtcPointQuery`; `userPtr` is the `PointSearch` that
    // `EmbreeScene::closest_point` passed, not otherwise touched during the call.
    let Some(args) = (unsafe { args.as_mut() }) else {
        return false;
    };
    let (Some(search), Some(query)) = (unsafe {
        (
            args.userPtr.cast::<PointSearch>().as_mut(),
            args.query.as_mut(),
        )
    }) else {
        return false;
    };
    // SAFETY: as above; the context is only read.
    let ctx = unsafe { args.context.as_ref() };
    search.offer(args.primID, ctx, args.similarityScale, query)
}

/// `v` in f64.
#[inline]
fn wide(v: Vec3A) -> glam::DVec3 {
    glam::DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// Copies the triangles into Embree-owned buffers (Embree pads them for its 16-byte loads).
fn fill_buffers(
    dev: &Device,
    geom: RTCGeometry,
    steps: &[&[Triangle]],
    vertices: usize,
) -> Result<(), EmbreeError> {
    let tris = steps[0];
    for (slot, step) in steps.iter().enumerate() {
        let vb = unsafe {
            rtcSetNewGeometryBuffer(
                geom,
                RTC_BUFFER_TYPE_VERTEX,
                slot as u32,
                RTC_FORMAT_FLOAT3,
                12,
                vertices,
            )
        };
        dev.check("rtcSetNewGeometryBuffer (vertices)")?;
        if vb.is_null() {
            return Err(EmbreeError::new(
                "rtcSetNewGeometryBuffer",
                "returned no buffer",
            ));
        }
        // SAFETY: Embree allocated `vertices` × 12 bytes, 4-byte aligned (at least 16), for
        // this buffer; every step holds `vertices / 3` triangles (checked by the caller).
        let vb = unsafe { std::slice::from_raw_parts_mut(vb.cast::<[f32; 3]>(), vertices) };
        for (i, t) in step.iter().enumerate() {
            for (k, v) in t.v.iter().enumerate() {
                vb[3 * i + k] = v.to_array();
            }
        }
    }
    let ib = unsafe {
        rtcSetNewGeometryBuffer(
            geom,
            RTC_BUFFER_TYPE_INDEX,
            0,
            RTC_FORMAT_UINT3,
            12,
            tris.len(),
        )
    };
    dev.check("rtcSetNewGeometryBuffer (indices)")?;
    if ib.is_null() {
        return Err(EmbreeError::new(
            "rtcSetNewGeometryBuffer",
            "returned no buffer",
        ));
    }
    // SAFETY: Embree allocated `tris.len()` × 12 bytes, 4-byte aligned, for this buffer.
    let ib = unsafe { std::slice::from_raw_parts_mut(ib.cast::<[u32; 3]>(), tris.len()) };
    for (i, idx) in ib.iter_mut().enumerate() {
        let base = 3 * i as u32;
        *idx = [base, base + 1, base + 2];
    }
    Ok(())
}

#[inline]
fn rtc_ray(r: &Ray) -> RTCRay {
    RTCRay {
        org_x: r.origin.x,
        org_y: r.origin.y,
        org_z: r.origin.z,
        tnear: r.t_min,
        dir_x: r.dir.x,
        dir_y: r.dir.y,
        dir_z: r.dir.z,
        time: r.time,
        tfar: r.t_max,
        mask: r.mask,
        id: 0,
        flags: 0,
    }
}

#[inline]
fn ray_hit(r: &Ray) -> RTCRayHit {
    RTCRayHit {
        ray: rtc_ray(r),
        hit: RTCHit {
            Ng_x: 0.0,
            Ng_y: 0.0,
            Ng_z: 0.0,
            u: 0.0,
            v: 0.0,
            primID: RTC_INVALID_GEOMETRY_ID,
            geomID: RTC_INVALID_GEOMETRY_ID,
            instID: [RTC_INVALID_GEOMETRY_ID; RTC_MAX_INSTANCE_LEVEL_COUNT],
        },
    }
}

/// `rtcIntersect1` leaves `geomID` invalid on a miss, and on a hit sets `tfar` to the distance.
#[inline]
fn hit_of(rh: &RTCRayHit) -> Option<(u32, f32)> {
    (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID).then_some((rh.hit.primID, rh.ray.tfar))
}

/// `rtcOccluded1` marks a hit by setting `tfar` to −∞.
#[inline]
fn occluded(r: &RTCRay) -> bool {
    r.tfar == f32::NEG_INFINITY
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rays;
    use quiver_rt::traverse::reference;
    use quiver_scenes::Scene;
    use rayon::prelude::*;

    /// (primitive, t), as [`EmbreeScene::closest_hit`] answers.
    type PrimT = Option<(u32, f32)>;

    /// Rays where Embree and the brute-force reference differ: another primitive, or a t off
    /// by more than 1e-4 relative, or hit against miss.
    fn closest_disagreements(
        scene: &EmbreeScene,
        tris: &[Triangle],
        rays: &[Ray],
    ) -> Vec<(usize, PrimT, PrimT)> {
        rays.par_iter()
            .enumerate()
            .filter_map(|(i, r)| {
                let e = scene.closest_hit(r);
                let q = reference::closest_hit(tris, r).map(|h| (h.prim, h.t));
                let same = match (e, q) {
                    (None, None) => true,
                    (Some((ep, et)), Some((qp, qt))) => {
                        ep == qp && (et - qt).abs() <= 1e-4 * qt.abs().max(et.abs())
                    }
                    _ => false,
                };
                (!same).then_some((i, e, q))
            })
            .collect()
    }

    fn check_scene(name: &str, random: usize) {
        let s = Scene::load(name).unwrap();
        let tris = s.triangles();
        let scene = EmbreeScene::new(&tris).unwrap();
        let camera = rays::camera_rays(&s.camera, 128);
        let mut lights: Vec<_> = s.lights.iter().map(|l| l.pos).collect();
        lights.push(s.camera.from); // soups have no lights
        let shadow = rays::shadow_rays(&quiver_rt::Bvh::new(&tris), &camera, &lights);
        let sets = [
            ("random", rays::random_rays(&s.bounds(), random, 5)),
            ("shadow", shadow),
            ("camera", camera),
        ];
        for (kind, set) in &sets {
            let allowed = set.len() / 1000;
            let bad = closest_disagreements(&scene, &tris, set);
            for (i, e, q) in &bad {
                println!("{name} {kind} ray {i}: embree {e:?}, reference {q:?}");
            }
            let hits = set
                .iter()
                .filter(|r| scene.closest_hit(r).is_some())
                .count();
            println!(
                "{name} {kind}: {} rays, {hits} hits, {} closest-hit disagreements",
                set.len(),
                bad.len()
            );
            assert!(hits > 0, "{name} {kind}: no ray hits anything");
            assert!(
                bad.len() <= allowed,
                "{name} {kind}: {} > {allowed}",
                bad.len()
            );

            let any_bad: Vec<usize> = (0..set.len())
                .into_par_iter()
                .filter(|&i| scene.any_hit(&set[i]) != reference::any_hit(&tris, &set[i]))
                .collect();
            for i in &any_bad {
                println!("{name} {kind} ray {i}: any-hit differs");
            }
            assert!(any_bad.len() <= allowed, "{name} {kind}: any-hit");

            // The stream forms answer exactly as the single-ray forms, coherent or not.
            let mut closest = vec![None; set.len()];
            scene.closest_hit_stream(set, &mut closest);
            let mut any = vec![false; set.len()];
            scene.any_hit_stream(set, &mut any);
            for (i, r) in set.iter().enumerate() {
                assert_eq!(closest[i], scene.closest_hit(r), "{name} {kind} ray {i}");
                assert_eq!(any[i], scene.any_hit(r), "{name} {kind} ray {i}");
            }
        }
    }

    #[test]
    fn embree_agrees_with_reference_on_tetra6() {
        check_scene("tetra6", 20_000);
    }

    #[test]
    fn embree_agrees_with_reference_on_soup() {
        check_scene("soup2000", 20_000);
    }

    #[test]
    fn embree_stream_on_tiles_matches_single_rays() {
        let s = Scene::load("tetra6").unwrap();
        let scene = EmbreeScene::new(&s.triangles()).unwrap();
        let eye = rays::camera_tiles(&s.camera, 100, 8); // partial tiles at the edges
        let mut out = vec![None; eye.len()];
        scene.closest_hit_stream(&eye, &mut out);
        for (r, o) in eye.iter().zip(&out) {
            assert_eq!(*o, scene.closest_hit(r));
        }
    }

    /// Motion-blurred instances (two to four linear keys each) answer, at every time, what
    /// the brute-force reference answers over the triangles placed by each instance's keys
    /// interpolated at that time; and a one-key list is a static instance.
    #[test]
    fn embree_moving_instances_meet_the_scene_placed_at_the_ray_time() {
        use glam::{Affine3A, Quat, Vec3};
        let s = Scene::load("tetra3").unwrap();
        let unit = s.triangles();
        let keys: Vec<Vec<Affine3A>> = (0..12)
            .map(|i| {
                let at = Vec3::new((i % 4) as f32 * 1.5, (i / 4) as f32 * 1.5, 0.0);
                let turn = Quat::from_rotation_z(0.3 * i as f32);
                (0..2 + i % 3)
                    .map(|k| {
                        let drift = Vec3::new(0.4, -0.2, 0.3) * k as f32 * (i % 5) as f32;
                        Affine3A::from_scale_rotation_translation(
                            Vec3::splat(1.0 + 0.1 * k as f32),
                            turn,
                            at + drift,
                        )
                    })
                    .collect()
            })
            .collect();
        let instances: Vec<(u32, &[Affine3A], u32)> =
            keys.iter().map(|k| (0, k.as_slice(), 1)).collect();
        let device = EmbreeDevice::new().unwrap();
        let scene = EmbreeScene::instanced_moving(&device, std::slice::from_ref(&unit), &instances)
            .unwrap();
        let mut bounds = quiver_rt::Aabb::EMPTY;
        for k in keys.iter().flatten() {
            for t in &unit {
                for v in t.v {
                    bounds.grow(k.transform_point3a(v));
                }
            }
        }
        for time in [0.0, 0.3, 0.5, 1.0] {
            // Embree interpolates the keys' matrices linearly between the two steps around t,
            // as a linear `Motion` does.
            let placed: Vec<Triangle> = keys
                .iter()
                .flat_map(|k| {
                    let m = quiver_rt::Motion::linear(k.clone()).at(time);
                    unit.iter().map(move |t| {
                        Triangle::new(
                            m.transform_point3a(t.v[0]),
                            m.transform_point3a(t.v[1]),
                            m.transform_point3a(t.v[2]),
                        )
                    })
                })
                .collect();
            // From random points of the scene box towards the placed triangles' centroids,
            // so that most rays meet something.
            let rays: Vec<Ray> = rays::random_rays(&bounds, 4000, 9)
                .into_iter()
                .enumerate()
                .map(|(k, r)| {
                    let t = &placed[k * 7919 % placed.len()];
                    let aim = (t.v[0] + t.v[1] + t.v[2]) / 3.0 - r.origin;
                    Ray::new(r.origin, aim.normalize()).with_time(time)
                })
                .collect();
            let mut hits = 0;
            let mut bad = 0;
            for r in &rays {
                let e = scene.closest_hit(r).map(|(_, t)| t);
                let q = reference::closest_hit(&placed, r).map(|h| h.t);
                hits += usize::from(q.is_some());
                let same = match (e, q) {
                    (None, None) => true,
                    (Some(et), Some(qt)) => (et - qt).abs() <= 1e-4 * qt.abs().max(et.abs()),
                    _ => false,
                };
                bad += usize::from(!same);
                assert_eq!(scene.any_hit(r), e.is_some(), "time {time}: {r:?}");
            }
            println!(
                "time {time}: {} rays, {hits} hits, {bad} disagreements",
                rays.len()
            );
            assert!(hits > rays.len() / 2, "time {time}: {hits} hits");
            assert!(bad <= rays.len() / 1000, "time {time}: {bad} disagreements");
        }
        let one_key = EmbreeScene::instanced_moving(
            &device,
            std::slice::from_ref(&unit),
            &[(0, &keys[0][..1], 1)],
        );
        let fixed = EmbreeScene::instanced(&device, &[unit], &[(0, keys[0][0], 1)]).unwrap();
        let one_key = one_key.unwrap();
        let mut hits = 0;
        for r in rays::random_rays(&bounds, 2000, 3) {
            let r = r.with_time(0.7);
            assert_eq!(one_key.closest_hit(&r), fixed.closest_hit(&r), "{r:?}");
            hits += usize::from(fixed.closest_hit(&r).is_some());
        }
        assert!(hits > 0);
        let none: &[Affine3A] = &[];
        assert!(EmbreeScene::instanced_moving(&device, &[vec![]], &[(0, none, 1)]).is_err());
    }

    /// Whether two closest-point distances agree: equal within a few f32 roundings of the
    /// distance and the scene's size (exact ties may name different triangles; an instance
    /// under a similarity is measured in its own space by Embree, in world space by quiver).
    fn same_distance(a: Option<f32>, b: Option<f32>, size: f32) -> bool {
        match (a, b) {
            (None, None) => true,
            (Some(a), Some(b)) => (a - b).abs() <= 8.0 * f32::EPSILON * (a.max(b) + size),
            _ => false,
        }
    }

    /// `EmbreeScene::closest_point` answers as `Bvh::closest_point` on random points (inside
    /// the box, on vertices and edges, far away), unlimited and cut off either side of the
    /// answer.
    #[test]
    fn embree_closest_point_agrees_with_quiver() {
        use crate::point_oracle::points;
        let tris = Scene::load("tetra4").unwrap().triangles();
        let scene = EmbreeScene::new(&tris).unwrap();
        let bvh = quiver_rt::Bvh::new(&tris);
        let size = scene_size(&tris);
        let mut same_prim = 0;
        let pts = points(&tris, 3000, 20.0, 3);
        for (k, &p) in pts.iter().enumerate() {
            let q = bvh.closest_point(p, f32::INFINITY).unwrap();
            let e = scene.closest_point(p, f32::INFINITY).unwrap();
            assert!(
                same_distance(Some(q.distance), Some(e.distance), size),
                "{p}: quiver {q:?}, Embree {e:?}"
            );
            assert_eq!(e.instance, None);
            let on = tris[e.prim as usize].closest_point(p).0;
            assert_eq!(on, e.point, "{p}");
            same_prim += usize::from(q.prim == e.prim);
            let max = q.distance * [0.5, 0.99, 1.01, 2.0][k % 4];
            let (q, e) = (bvh.closest_point(p, max), scene.closest_point(p, max));
            let (q, e) = (q.map(|h| h.distance), e.map(|h| h.distance));
            assert!(same_distance(q, e, size), "{p} within {max}: {q:?} {e:?}");
        }
        println!("{same_prim} of {} name the same triangle", pts.len());
        assert!(same_prim >= pts.len() * 99 / 100);
        assert_eq!(scene.closest_point(glam::Vec3A::NAN, 1.0), None);
        assert_eq!(scene.closest_point(glam::Vec3A::ZERO, -1.0), None);
    }

    /// `of_world_for_points` answers as quiver's `World::closest_point` (world-space
    /// distances) under rotations with uniform scales (similarities, measured in instance
    /// space), non-uniform scales and shears (measured in world space), and the identity.
    #[test]
    fn embree_instanced_closest_point_agrees_with_the_world() {
        use crate::point_oracle::points;
        use glam::{Affine3A, Mat3, Quat, Vec3};
        let unit = Scene::load("tetra3").unwrap().triangles();
        let other = Scene::load("soup200").unwrap().triangles();
        let placements: Vec<(u32, Affine3A)> = (0..16)
            .map(|i| {
                let at = Vec3::new((i % 4) as f32 * 1.7, (i / 4) as f32 * 1.7, 0.1 * i as f32);
                let turn = Quat::from_rotation_z(0.4 * i as f32) * Quat::from_rotation_x(0.3);
                let m = match i % 4 {
                    0 => Affine3A::from_translation(at),
                    1 => Affine3A::from_scale_rotation_translation(Vec3::splat(0.7), turn, at),
                    2 => Affine3A::from_scale_rotation_translation(
                        Vec3::new(1.0, 0.4, 2.0),
                        turn,
                        at,
                    ),
                    _ => Affine3A::from_mat3_translation(
                        Mat3::from_cols(Vec3::X, Vec3::new(0.6, 1.0, 0.0), Vec3::Z),
                        at,
                    ),
                };
                ((i % 2) as u32, m)
            })
            .collect();
        let mut b = quiver_rt::World::builder();
        let ids = [
            b.add_triangles(unit.clone()),
            b.add_triangles(other.clone()),
        ];
        for &(g, m) in &placements {
            b.add_instance(quiver_rt::Instance::of(ids[g as usize]).transform(m));
        }
        let world = b.build(&quiver_rt::BuildOptions::default()).unwrap();
        let device = EmbreeDevice::new().unwrap();
        let scene = EmbreeScene::of_world_for_points(&device, &world).unwrap();
        // Embree 3.13's own instances miss triangles under the shrinking similarities.
        let plain = EmbreeScene::of_world(&device, &world).unwrap();
        let placed: Vec<Triangle> = placements
            .iter()
            .flat_map(|&(g, m)| {
                [&unit, &other][g as usize].iter().map(move |t| Triangle {
                    v: t.v.map(|v| m.transform_point3a(v)),
                })
            })
            .collect();
        let size = scene_size(&placed);
        let pts = points(&placed, 3000, 20.0, 5);
        let mut same = 0;
        let mut plain_wrong = 0;
        for (k, &p) in pts.iter().enumerate() {
            let q = world.closest_point(p, f32::INFINITY).unwrap();
            // Beyond the answer by half of it and a few roundings (points on a triangle too).
            let near = q.distance * 1.5 + 1e-5 * size;
            let wrong = |s: &EmbreeScene| {
                let d = s.closest_point(p, near).map(|h| h.distance);
                !same_distance(Some(q.distance), d, size)
            };
            assert!(!wrong(&scene), "{p} within {near}");
            plain_wrong += usize::from(wrong(&plain));
            let e = scene.closest_point(p, f32::INFINITY).unwrap();
            assert!(
                same_distance(Some(q.distance), Some(e.distance), size),
                "{p}: quiver {q:?}, Embree {e:?}"
            );
            same += usize::from(e.instance == Some(q.instance.0) && e.prim == q.prim);
            // A cut-off within roundings of the answer may fall either side of it: the two
            // engines measure an instance under a similarity in different spaces.
            let max = q.distance * [0.5, 0.99, 1.01, 2.0][k % 4];
            if same_distance(Some(max), Some(q.distance), size) {
                continue;
            }
            let (q, e) = (world.closest_point(p, max), scene.closest_point(p, max));
            let (q, e) = (q.map(|h| h.distance), e.map(|h| h.distance));
            assert!(same_distance(q, e, size), "{p} within {max}: {q:?} {e:?}");
        }
        println!(
            "{same} of {} name the same instance and triangle; Embree's unscaled instances \
             wrong at {plain_wrong}",
            pts.len()
        );
        // Two in five points lie on vertices or edges, shared by several triangles at equal
        // distance: Embree breaks those ties by its own rounding in instance space.
        assert!(same >= pts.len() * 95 / 100);
    }

    /// The largest coordinate magnitude plus the extent of `tris`' box.
    fn scene_size(tris: &[Triangle]) -> f32 {
        let b = tris
            .iter()
            .fold(quiver_rt::Aabb::EMPTY, |b, t| b.union(&t.bounds()));
        (b.max - b.min).max_element() + b.min.abs().max(b.max.abs()).max_element()
    }

    #[test]
    fn embree_device_reports_version_and_builds_empty_scenes() {
        let device = EmbreeDevice::with_threads(1).unwrap();
        println!(
            "Embree {} (ray streams: {})",
            device.version(),
            device.ray_streams()
        );
        assert!(device.version().starts_with("3."));
        let empty = EmbreeScene::on_device(&device, &[]).unwrap();
        let ray = Ray::new(glam::Vec3A::ZERO, glam::Vec3A::X);
        assert_eq!(empty.closest_hit(&ray), None);
        assert!(!empty.any_hit(&ray));
    }

    #[test]
    fn embree_isa_follows_a_forced_configuration() {
        // Embree runs the ISA its configuration names when the CPU has it.
        let sse = EmbreeDevice::with_config(Some("isa=sse4.2")).unwrap();
        assert_eq!(sse.isa(), "sse");
        if std::arch::is_x86_feature_detected!("avx2") {
            let avx2 = EmbreeDevice::with_config(Some("isa=avx2")).unwrap();
            assert_eq!(avx2.isa(), "avx2");
        }
        println!("default: {}", EmbreeDevice::new().unwrap().isa());
    }

    #[test]
    fn embree_memory_monitor_counts_the_bvh() {
        let s = Scene::load("tetra6").unwrap();
        let tris = s.triangles();
        let device = EmbreeDevice::with_threads(1).unwrap();
        let scene = EmbreeScene::on_device(&device, &tris).unwrap();
        let bytes = scene.bvh_bytes();
        println!("Embree BVH over {} triangles: {bytes} bytes", tris.len());
        // At least the triangles' own data (three vertices of 12 bytes each) and at most a
        // generous bound: a broken monitor reads 0 or garbage.
        assert!(
            bytes >= 36 * tris.len() && bytes < 1000 * tris.len(),
            "{bytes}"
        );
        let bigger =
            EmbreeScene::on_device(&device, &Scene::load("tetra7").unwrap().triangles()).unwrap();
        assert!(
            bigger.bvh_bytes() > 2 * bytes,
            "{} vs {bytes}",
            bigger.bvh_bytes()
        );
        drop(scene);
        drop(bigger);
        let empty = EmbreeScene::on_device(&device, &[]).unwrap();
        assert!(empty.bvh_bytes() < 36 * tris.len());
    }

    #[test]
    fn embree_errors_are_results() {
        let device = EmbreeDevice::new().unwrap();
        let dev = &device.inner;
        dev.check("nothing").unwrap();
        let geom = unsafe { rtcNewGeometry(dev.raw, 999) }; // no such geometry type
        assert!(geom.is_null());
        let err = dev.check("rtcNewGeometry").unwrap_err();
        println!("{err}");
        assert!(err.message.contains("invalid geometry type"), "{err}");
        dev.check("after the error was taken").unwrap();
    }
}
