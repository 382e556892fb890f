//! The compiled kernels kept across runs (beyond the paper, whose solver
//! ran on the CPU): a driver's pipeline cache (wgpu's `PipelineCache`,
//! Vulkan's `VkPipelineCache`) loaded when the device opens and saved once
//! the kernels are made, so a later run on the same adapter and driver
//! skips most of their compilation. The file is named by wgpu's key for the
//! adapter (vendor and device) in the user's cache folder
//! (`RADIOSITY_CACHE_DIR`, else `$XDG_CACHE_HOME/radiosity`, else
//! `~/.cache/radiosity`; `RADIOSITY_CACHE_DIR=off` turns it off). It is
//! written to a temporary file and renamed over the old one, so a run
//! stopped or a second run at the same time never leaves half a file; it
//! carries a length and a checksum of its own, so a damaged file is
//! compiled over, not given to the driver. The cache only saves time: any
//! failure to read or write it is a compile, never an error.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Duration;

/// The file's first bytes, with the format's version.
const MAGIC: &[u8; 8] = b"RADPLC01";

/// How the kernels of a device were made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CacheState {
    /// `RADIOSITY_CACHE_DIR=off`, or no cache folder known.
    Off,
    /// The adapter keeps no pipeline cache (wgpu has them on Vulkan).
    Unsupported,
    /// No usable cache file: the kernels were compiled (and saved).
    Compiled,
    /// A cache file was given to the driver.
    Loaded,
}

impl CacheState {
    /// The state as `--stats` names it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            CacheState::Off => "off",
            CacheState::Unsupported => "unsupported",
            CacheState::Compiled => "compiled",
            CacheState::Loaded => "loaded",
        }
    }
}

/// A device's pipeline cache and where it is kept.
pub(crate) struct KernelCache {
    cache: Option<wgpu::PipelineCache>,
    path: Option<PathBuf>,
    state: CacheState,
    /// Time spent making the kernels so far.
    time: Mutex<Duration>,
}

/// The cache folder the environment names, if any.
fn folder() -> Option<PathBuf> {
    let from = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if let Some(dir) = from("RADIOSITY_CACHE_DIR") {
        return (dir != "off").then(|| PathBuf::from(dir));
    }
    if let Some(dir) = from("XDG_CACHE_HOME") {
        return Some(PathBuf::from(dir).join("radiosity"));
    }
    from("HOME").map(|home| PathBuf::from(home).join(".cache").join("radiosity"))
}

/// FNV-1a over `bytes`: enough to tell a damaged file.
fn checksum(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The driver's data in the file at `path`, if it is whole.
fn read(path: &Path) -> Option<Vec<u8>> {
    let bytes = std::fs::read(path).ok()?;
    let rest = bytes.strip_prefix(MAGIC)?;
    let (length, rest) = rest.split_first_chunk::<8>()?;
    let (sum, data) = rest.split_first_chunk::<8>()?;
    (u64::from_le_bytes(*length) == data.len() as u64 && u64::from_le_bytes(*sum) == checksum(data))
        .then(|| data.to_vec())
}

/// Writes `data` to `path` through a temporary file renamed over it.
fn write(path: &Path, data: &[u8]) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut bytes = Vec::with_capacity(data.len() + 24);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&(data.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&checksum(data).to_le_bytes());
    bytes.extend_from_slice(data);
    let temporary = path.with_extension(format!("{}.tmp", std::process::id()));
    std::fs::write(&temporary, &bytes)?;
    std::fs::rename(&temporary, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&temporary);
    })
}

impl KernelCache {
    /// The cache of `device`, opened on `adapter` (loaded from its file
    /// where there is a whole one).
    pub(crate) fn open(device: &wgpu::Device, info: &wgpu::AdapterInfo) -> KernelCache {
        let off = |state| KernelCache {
            cache: None,
            path: None,
            state,
            time: Mutex::default(),
        };
        let Some(dir) = folder() else {
            return off(CacheState::Off);
        };
        let key = wgpu::util::pipeline_cache_key(info);
        let (Some(key), true) = (
            key,
            device.features().contains(wgpu::Features::PIPELINE_CACHE),
        ) else {
            return off(CacheState::Unsupported);
        };
        let path = dir.join(format!("{key}.bin"));
        let data = read(&path);
        // SAFETY: the data is what `PipelineCache::get_data` gave a run on
        // an adapter of the same key (the file is named by it), whole by
        // its length and checksum; wgpu checks its own header (version,
        // backend, adapter) and falls back to an empty cache where it does
        // not match.
        let cache = unsafe {
            device.create_pipeline_cache(&wgpu::PipelineCacheDescriptor {
                label: Some("radiosity kernels"),
                data: data.as_deref(),
                fallback: true,
            })
        };
        KernelCache {
            cache: Some(cache),
            path: Some(path),
            state: if data.is_some() {
                CacheState::Loaded
            } else {
                CacheState::Compiled
            },
            time: Mutex::default(),
        }
    }

    /// The cache to make pipelines with.
    pub(crate) fn get(&self) -> Option<&wgpu::PipelineCache> {
        self.cache.as_ref()
    }

    /// How the kernels were made.
    pub(crate) fn state(&self) -> CacheState {
        self.state
    }

    /// Time spent making kernels on this device.
    pub(crate) fn time(&self) -> Duration {
        *self
            .time
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Books `time` spent making kernels and saves what the driver holds
    /// now (best effort: a cache that cannot be written is skipped).
    pub(crate) fn made(&self, time: Duration) {
        *self
            .time
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) += time;
        if let (Some(cache), Some(path)) = (&self.cache, &self.path)
            && let Some(data) = cache.get_data()
            && read(path).as_deref() != Some(&data[..])
        {
            let _ = write(path, &data);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cache_file_reads_back_whole_and_refuses_damage() {
        let dir = std::env::temp_dir().join(format!("radiosity-cache-{}", std::process::id()));
        let path = dir.join("key.bin");
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        write(&path, &data).unwrap();
        assert_eq!(read(&path).as_deref(), Some(&data[..]));
        let whole = std::fs::read(&path).unwrap();
        // Cut short, one byte changed, the wrong magic: none is read.
        std::fs::write(&path, &whole[..whole.len() - 1]).unwrap();
        assert_eq!(read(&path), None);
        let mut changed = whole.clone();
        changed[500] ^= 1;
        std::fs::write(&path, &changed).unwrap();
        assert_eq!(read(&path), None);
        let mut magic = whole;
        magic[0] = b'X';
        std::fs::write(&path, &magic).unwrap();
        assert_eq!(read(&path), None);
        // No temporary file is left beside it.
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(left.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
