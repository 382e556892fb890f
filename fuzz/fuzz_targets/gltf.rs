//! The glTF loader from bytes (`gltf::load_slice`): any bytes, as JSON with
//! an external file or as GLB, load to well-formed surfaces with an
//! appearance that matches them, or give an error; never a panic, a hang or
//! a huge allocation. No file is read or written: URIs resolve to the
//! input's external part (see `radiosity_fuzz::split_gltf`).
#![no_main]

use libfuzzer_sys::fuzz_target;

/// Inputs larger than this are skipped (tools/fuzz.sh passes the same
/// `-max_len`; the cap holds when the target is run on other files).
const MAX_INPUT: usize = 64 * 1024;

fuzz_target!(|data: &[u8]| {
    if data.len() > MAX_INPUT {
        return;
    }
    match radiosity_fuzz::load_gltf(data) {
        Ok((scene, appearance)) => {
            radiosity_fuzz::check_scene(&scene);
            radiosity_fuzz::check_appearance(&scene, &appearance);
        }
        Err(error) => radiosity_fuzz::check_error(&error),
    }
});
