//! What this process and this machine hold, read where the system tells
//! it (`/proc` on Linux, `getrusage` elsewhere on Unix): the peak and
//! current resident set and the memory available, for the run's report
//! and its memory check ([`super::check`]). Beyond the paper.

/// A field of `/proc/self/status` or `/proc/meminfo` in bytes (the files
/// give KiB).
fn proc_field(path: &str, field: &str) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    let line = text.lines().find(|l| l.starts_with(field))?;
    let kib: u64 = line[field.len()..]
        .trim_start_matches(':')
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    Some(kib.saturating_mul(1024))
}

/// The most memory this process has held resident so far (Linux: `VmHWM`;
/// elsewhere `getrusage`'s `ru_maxrss`).
#[must_use]
pub fn peak_resident_bytes() -> Option<u64> {
    proc_field("/proc/self/status", "VmHWM").or_else(rusage_max_rss)
}

/// The memory this process holds resident now (Linux only).
#[must_use]
pub fn resident_bytes() -> Option<u64> {
    proc_field("/proc/self/status", "VmRSS")
}

/// The memory the machine can give without swapping (Linux:
/// `MemAvailable`).
#[must_use]
pub fn available_bytes() -> Option<u64> {
    proc_field("/proc/meminfo", "MemAvailable")
}

#[cfg(unix)]
fn rusage_max_rss() -> Option<u64> {
    // SAFETY: getrusage writes into the zeroed struct we own.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return None;
    }
    let max = u64::try_from(usage.ru_maxrss).ok()?;
    // Bytes on macOS, KiB elsewhere.
    Some(if cfg!(target_os = "macos") {
        max
    } else {
        max * 1024
    })
}

#[cfg(not(unix))]
fn rusage_max_rss() -> Option<u64> {
    None
}

/// Resets this process's peak resident set to its current one, so a later
/// [`peak_resident_bytes`] measures what came after (Linux 4.0 and later:
/// `/proc/self/clear_refs`); freed heap is first given back to the system
/// where the allocator allows. Returns false where this is not possible.
pub fn reset_peak() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory of glibc's heap.
    unsafe {
        libc::malloc_trim(0);
    }
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_has_a_peak() {
        // The resident size first: other tests run in threads of this
        // process, and the peak read after it can only be larger, up to the
        // kernel's per-thread batching of its RSS counters (a few pages a
        // thread), for which 4 MiB leaves room.
        let now = resident_bytes();
        let peak = peak_resident_bytes().unwrap();
        assert!(peak > 1 << 20);
        if let Some(now) = now {
            assert!(
                now <= peak + (4 << 20),
                "resident {now} above the peak {peak}"
            );
        }
    }
}
