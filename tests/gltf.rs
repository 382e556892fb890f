//! glTF input through the `radiosity` command: a run that fails on a bad
//! `.glb` writes none of its outputs. The loader's and the bakes' own tests
//! are in crates/radiosity/tests/ (gltf.rs, gltf_errors.rs, export.rs).

/// A run that fails on bad input writes none of its outputs, and the
/// command exits non-zero with the loader's message.
#[test]
fn a_bad_gltf_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.glb");
    std::fs::write(&bad, b"glTF\x02\0\0\0\xff\xff\0\0").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env("RADIOSITY_DEVICE", "cpu")
        .arg("render")
        .arg(&bad)
        .arg("--output")
        .arg(dir.path().join("p.png"))
        .arg("--bake")
        .arg(dir.path().join("b.glb"))
        .arg("--ply")
        .arg(dir.path().join("m.ply"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        stderr.trim(),
        format!(
            "error: {}: truncated GLB: the header gives 65535 bytes, the file has 12",
            bad.display()
        )
    );
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, [std::ffi::OsString::from("bad.glb")]);
}
