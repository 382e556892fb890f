//! The GPU back end of progressive radiosity (Wallace, Elmquist & Haines,
//! SIGGRAPH 1989; Wong & Tsang 1993), beyond the paper: the same queries the
//! CPU answers, as WGSL compute kernels driven through wgpu, so that they
//! run on any GPU (Vulkan, Metal, DX12) and, for the tests, on a software
//! Vulkan adapter (Mesa's lavapipe).
//!
//! Modules, one concern each: [`adapter`] (finding and opening an adapter,
//! naming it), [`policy`] (the device a run takes: which settings the GPU
//! runs, what `--device auto|gpu|cpu` opens), [`shaders`] (the kernels'
//! source, with the numbers they share with Rust generated from it), [`device_scene`] (the scene's triangles and BVH on the
//! device), [`kernel_cache`] (the compiled kernels kept across runs),
//! `wgpu_io` (buffers, bindings, readbacks, device errors),
//! [`gather`] (the default method's transfers), [`trace`] (shadow
//! segments against the scene: a binary
//! bounding-volume hierarchy over the surfaces' triangles, the very tree
//! the CPU's BVH builds, walked by the `occluded` kernel (`trace/`)
//! with a watertight triangle test). The CPU implementation is the oracle
//! every kernel is tested against.

pub mod adapter;
pub mod device_scene;
pub mod gather;
pub mod kernel_cache;
pub mod policy;
pub mod shaders;
pub mod trace;
mod wgpu_io;

pub use adapter::{DeviceChoice, Gpu, GpuError};
pub use gather::GpuBackend;
pub use kernel_cache::CacheState;

/// The environment variable that makes the GPU tests require an adapter:
/// set (to anything but `0`) they fail without one; unset they say they
/// did not run. CI sets it, with Mesa's software Vulkan installed.
pub const REQUIRE_ADAPTER: &str = "RADIOSITY_REQUIRE_GPU";

/// The adapter the GPU tests run on: any (software ones included), or
/// `None` with a note on standard error when there is none and
/// [`REQUIRE_ADAPTER`] is not set.
///
/// # Panics
///
/// When [`REQUIRE_ADAPTER`] is set and no adapter opens.
#[must_use]
pub fn test_adapter() -> Option<Gpu> {
    let required = std::env::var(REQUIRE_ADAPTER).is_ok_and(|v| v != "0");
    match Gpu::open(DeviceChoice::Gpu) {
        Ok(gpu) => gpu,
        Err(e) if required => panic!("{REQUIRE_ADAPTER} is set: {e}"),
        Err(e) => {
            eprintln!("GPU test did not run: {e} (set {REQUIRE_ADAPTER} to require one)");
            None
        }
    }
}
