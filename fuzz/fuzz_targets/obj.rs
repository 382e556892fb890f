//! The OBJ parser (with an MTL library): any bytes load or give an error,
//! never a panic, a hang or a malformed surface.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match radiosity_fuzz::load_obj(data) {
        Ok(scene) => radiosity_fuzz::check_scene(&scene),
        Err(error) => radiosity_fuzz::check_error(&error),
    }
});
