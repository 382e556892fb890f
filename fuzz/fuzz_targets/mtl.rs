//! The MTL parser alone: any bytes give materials in range or an error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use radiosity::scene::mtl;

fuzz_target!(|data: &[u8]| {
    let mut warnings = Vec::new();
    let path = std::path::Path::new("fuzz.mtl");
    match mtl::parse_mtl(path, data, &radiosity_fuzz::LIMITS, &mut warnings) {
        Ok(materials) => {
            for m in materials.values() {
                assert!(m.rho.min_element() >= 0.0 && m.rho.max_element() < 1.0);
                assert!(m.emission.min_element() >= 0.0 && m.emission.is_finite());
                assert!(m.transmittance.min_element() >= 0.0 && m.transmittance.max_element() <= 1.0);
            }
        }
        Err(error) => radiosity_fuzz::check_error(&error),
    }
});
