//! The lightmap rewrite from bytes (`lightmap::rewrite_blank`): any glTF
//! the loader accepts gets lightmap coordinates and a rewritten document,
//! or one error; never a panic, a hang or a huge allocation. The rewrite
//! reads every vertex attribute through its accessor (including those the
//! loader does not read: normals, tangents, joints, morph targets), so it
//! is fuzzed beyond the loader. A document written reads back through the
//! loader with `TEXCOORD_1` on every placed primitive, inside [0, 1].
#![no_main]

use libfuzzer_sys::fuzz_target;

/// Inputs larger than this are skipped, as for the `gltf` target.
const MAX_INPUT: usize = 64 * 1024;

fuzz_target!(|data: &[u8]| {
    if data.len() > MAX_INPUT {
        return;
    }
    if let Ok((_, appearance)) = radiosity_fuzz::load_gltf(data) {
        radiosity_fuzz::check_lightmap(&appearance);
    }
});
