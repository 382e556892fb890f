//! The IES LM-63 photometric reader (`ies::parse`): any bytes give a
//! profile with finite, non-negative candela everywhere and a finite flux,
//! or an error naming a line; never a panic, a hang or a huge allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;

/// Inputs larger than this are skipped (tools/fuzz.sh passes the same
/// `-max_len`).
const MAX_INPUT: usize = 64 * 1024;

fuzz_target!(|data: &[u8]| {
    if data.len() <= MAX_INPUT {
        radiosity_fuzz::check_ies(data);
    }
});
