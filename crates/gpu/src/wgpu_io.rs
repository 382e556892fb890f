//! What every kernel's host side needs from wgpu (beyond the paper):
//! storage buffers (never empty, which cannot be bound), bind group
//! entries, reading a buffer back once the device is done, and the errors
//! a device reports outside a scope (a lost device) kept instead of
//! panicking, so a device that fails mid-run is a fault to survive.

use std::sync::{Arc, Mutex};

use bytemuck::Pod;
use wgpu::util::DeviceExt;

use crate::{Gpu, GpuError};

/// Errors `gpu` reports outside an error scope (a lost device) from now
/// on, kept (the first) instead of wgpu's default, which panics.
pub(crate) fn catch_uncaptured(gpu: &Gpu) -> Arc<Mutex<Option<String>>> {
    let uncaptured = Arc::new(Mutex::new(None));
    let sink = uncaptured.clone();
    gpu.device
        .on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut slot) = sink.lock() {
                slot.get_or_insert_with(|| e.to_string());
            }
        }));
    uncaptured
}

/// The first `bytes` of `readback`, once the device has done what was
/// submitted (the copy into it last); a device error on the way, or one
/// reported outside a scope (`uncaptured`), is the caller's.
pub(crate) fn read_back(
    gpu: &Gpu,
    readback: &wgpu::Buffer,
    bytes: u64,
    uncaptured: &Mutex<Option<String>>,
) -> Result<Vec<u8>, GpuError> {
    let slice = readback.slice(..bytes.max(4));
    let (sender, receiver) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = sender.send(r);
    });
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| gpu.failed(e))?;
    match receiver.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(gpu.failed(e)),
        Err(_) => return Err(gpu.failed("the readback was never mapped")),
    }
    if let Some(message) = uncaptured.lock().ok().and_then(|s| s.clone()) {
        return Err(gpu.failed(message));
    }
    let out = {
        let view = slice.get_mapped_range().map_err(|e| gpu.failed(e))?;
        view[..bytes as usize].to_vec()
    };
    readback.unmap();
    Ok(out)
}

/// `items`, or one zeroed element when there are none.
pub(crate) fn nonempty<T: Pod + Default>(mut items: Vec<T>) -> Vec<T> {
    if items.is_empty() {
        items.push(T::default());
    }
    items
}

/// A read-only storage buffer holding `items`.
pub(crate) fn storage<T: Pod>(gpu: &Gpu, label: &str, items: &[T]) -> wgpu::Buffer {
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(items),
            usage: wgpu::BufferUsages::STORAGE,
        })
}

/// Binding `binding` of the kernel's group to all of `buffer`.
pub(crate) fn entry(binding: impl Into<u32>, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding: binding.into(),
        resource: buffer.as_entire_binding(),
    }
}
