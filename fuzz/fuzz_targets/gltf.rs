//! The glTF loader from bytes (`gltf::load_slice`): any bytes, as JSON with
//! an external file or as GLB, load to well-formed surfaces with an
//! appearance that matches them, or give an error; never a panic, a hang or
//! a huge allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match radiosity_fuzz::load_gltf(data) {
        Ok((scene, appearance)) => {
            radiosity_fuzz::check_scene(&scene);
            radiosity_fuzz::check_appearance(&scene, &appearance);
        }
        Err(error) => radiosity_fuzz::check_error(&error),
    }
});
