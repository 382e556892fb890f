//! Unit tests of the OBJ reader, with the MTL libraries it reads and the
//! text reading both share: parsed scenes, and the exact message of each
//! kind of bad input.

use super::*;
use crate::geometry;

fn parse_with(obj: &str, mtl: &str) -> Result<Scene, SceneError> {
    let mtl = mtl.to_string();
    parse("t", Path::new("t.obj"), obj, &mut |name: &str| {
        if name == "t.mtl" {
            Ok((PathBuf::from("t.mtl"), mtl.clone()))
        } else {
            Err(SceneError::Io {
                location: Location::file(Path::new(name)),
                source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
            })
        }
    })
}

fn message(obj: &str, mtl: &str) -> String {
    parse_with(obj, mtl).unwrap_err().to_string()
}

const MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 10 10 10\nnewmtl grey\nKd 0.5\n";
const HEAD: &str = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl light\n";

#[test]
fn quad_stays_whole_and_concave_face_is_triangulated() {
    let obj = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.25 0\n\
               usemtl light\nf 1 2 3 4\nusemtl grey\nf 1 2 3 5\n";
    // Second face: (0,0) (1,0) (1,1) (0.5,0.25) is concave at (0.5,0.25).
    let scene = parse_with(obj, MTL).unwrap();
    assert_eq!(scene.surfaces[0].polygon.len(), 4);
    assert_eq!(scene.surfaces.len(), 3);
    let concave_area: f64 = scene.surfaces[1..].iter().map(|s| s.area).sum();
    let expected = geometry::area(&[
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(0.5, 0.25, 0.0),
    ]);
    assert!((concave_area - expected).abs() < 1e-12);
    assert!(scene.surfaces[1..].iter().all(|s| s.face == 1));
    assert_eq!(scene.surfaces[1].rho, DVec3::splat(0.5));
}

#[test]
fn errors_name_the_line() {
    let obj = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl light\nf 1 2 9\n";
    assert_eq!(
        message(obj, MTL),
        "t.obj:6: vertex index 9 is out of range (3 defined so far)"
    );
}

#[test]
fn reflectance_of_one_is_rejected_in_the_mtl() {
    let obj = "mtllib t.mtl\nv 0 0 0\n";
    let message = message(obj, "newmtl a\nKd 1 0.5 0.5\n");
    assert!(message.starts_with("t.mtl:2:"), "{message}");
}

#[test]
fn negative_indices_and_slashes() {
    let obj = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvn 0 0 1\n\
               usemtl light\nf -3/1/1 -2//1 -1/2\n";
    let scene = parse_with(obj, MTL).unwrap();
    assert_eq!(scene.surfaces.len(), 1);
    assert_eq!(scene.surfaces[0].normal, DVec3::Z);
}

#[test]
fn malformed_references_are_errors() {
    for (face, expected) in [
        (
            "f 1/2/3/4 2 3",
            "t.obj:7: '1/2/3/4' is not a vertex reference (v, v/vt, v//vn or v/vt/vn)",
        ),
        (
            "f 1/x/2 2 3",
            "t.obj:7: 'x' in '1/x/2' is not a texture coordinate index",
        ),
        (
            "f 1/ 2 3",
            "t.obj:7: '1/' is not a vertex reference (v, v/vt, v//vn or v/vt/vn)",
        ),
        (
            "f 1// 2 3",
            "t.obj:7: '1//' is not a vertex reference (v, v/vt, v//vn or v/vt/vn)",
        ),
        (
            "f 1/1 2 3",
            "t.obj:7: texture coordinate index 1 is out of range (0 defined so far)",
        ),
        (
            "f 1//1 2 3",
            "t.obj:7: normal index 1 is out of range (0 defined so far)",
        ),
    ] {
        assert_eq!(message(&format!("{HEAD}{face}\n"), MTL), expected);
    }
}

#[test]
fn wrong_counts_of_numbers_are_errors() {
    let mtl = MTL.replace("Kd 0.5 0.5 0.5", "Kd 0.5 0.5");
    assert_eq!(
        message(HEAD, &mtl),
        "t.mtl:2: 'Kd' takes 1 number (grey) or 3 (r g b), found 2"
    );
    let mtl = MTL.replace("Ke 10 10 10", "Ke 10 10 10 10");
    assert_eq!(
        message(HEAD, &mtl),
        "t.mtl:3: 'Ke' takes 1 number (grey) or 3 (r g b), found 4"
    );
    assert_eq!(
        message(&format!("{HEAD}vn 0 1\n"), MTL),
        "t.obj:7: 'vn' takes x y z, found 2 numbers"
    );
    assert_eq!(
        message(&format!("{HEAD}v 1 2 3 4 5\n"), MTL),
        "t.obj:7: a vertex 'v' takes x y z (optionally w, or r g b), found 5 numbers"
    );
}

#[test]
fn self_intersecting_faces_are_errors() {
    let bow_tie = "mtllib t.mtl\nv 0 0 0\nv 1 1 0\nv 1 0 0\nv 0 1 0\nusemtl light\nf 1 2 3 4\n";
    assert_eq!(
        message(bow_tie, MTL),
        "t.obj:7: the face's outline crosses itself (its edge from corner 1 to 2 meets its \
         edge from corner 3 to 4): a face must be a simple polygon, so split it into faces \
         that are"
    );
    let mut pentagram = String::from("mtllib t.mtl\n");
    for i in 0..5 {
        let a = std::f64::consts::TAU * (2 * i) as f64 / 5.0;
        pentagram += &format!("v {} {} 0\n", a.cos(), a.sin());
    }
    pentagram += "usemtl light\nf 1 2 3 4 5\n";
    let message = message(&pentagram, MTL);
    assert!(
        message.starts_with("t.obj:8: the face's outline crosses itself"),
        "{message}"
    );
}

#[test]
fn byte_order_mark_and_old_mac_line_ends_are_read() {
    let obj = format!("\u{feff}{HEAD}f 1 2 3 4\n");
    let mtl = format!("\u{feff}{MTL}");
    assert_eq!(parse_with(&obj, &mtl).unwrap().surfaces.len(), 1);
    let obj = format!("{HEAD}f 1 2 3 4\n").replace('\n', "\r");
    let mtl = MTL.replace('\n', "\r");
    assert_eq!(parse_with(&obj, &mtl).unwrap().surfaces.len(), 1);
    let obj = format!("{HEAD}f 1 2 9\n").replace('\n', "\r");
    assert!(message(&obj, MTL).starts_with("t.obj:7: vertex index 9"));
}

#[test]
fn nul_byte_is_named_with_its_line() {
    let obj = format!("{HEAD}# a comment \0 with a NUL\nf 1 2 3 4\n");
    assert_eq!(
        message(&obj, MTL),
        "t.obj:7: a NUL byte: this looks like a binary file, not Wavefront OBJ/MTL text"
    );
}

#[test]
fn long_names_are_cut_in_messages() {
    let name = "x".repeat(1_000_000);
    let message = message(&format!("{HEAD}usemtl {name}\n"), MTL);
    assert_eq!(
        message,
        format!(
            "t.obj:7: material '{}...' (1000000 bytes) is not defined in any loaded \
             material library (mtllib)",
            "x".repeat(40)
        )
    );
}

#[test]
fn limits_name_the_option_that_raises_them() {
    let limits = Limits {
        max_corners: 3,
        max_faces: 1,
        max_vertices: 4,
        max_line_bytes: 20,
        ..Limits::default()
    };
    let run = |obj: &str| {
        parse_bytes(
            "t",
            Path::new("t.obj"),
            obj.as_bytes(),
            &limits,
            &mut |_| Ok((PathBuf::from("t.mtl"), MTL.as_bytes().to_vec())),
        )
        .unwrap_err()
        .to_string()
    };
    assert_eq!(
        run(&format!("{HEAD}f 1 2 3 4\n")),
        "t.obj:7: the face has 4 corners, more than the limit of 3 (raise it with --max-corners)"
    );
    assert_eq!(
        run(&format!("{HEAD}f 1 2 3\nf 1 3 4\n")),
        "t.obj:8: more than 1 faces, the limit (raise it with --max-faces)"
    );
    assert_eq!(
        run(&format!("{HEAD}v 0 0 1\n")),
        "t.obj:7: more than 4 vertices, the limit (raise it with --max-vertices)"
    );
    assert_eq!(
        run(&format!("{HEAD}# a comment that is too long\n")),
        "t.obj:7: the line is 28 bytes long, more than the limit of 20 bytes (raise it with \
         --max-line-length)"
    );
    assert_eq!(
        run(&format!("{HEAD}f 1 \\\n2 \\\n3 \\\n4 \\\n1 \\\n2 \\\n3\n")),
        "t.obj:7: the line is 21 bytes long, more than the limit of 20 bytes (raise it with \
         --max-line-length)"
    );
}

#[test]
fn unknown_statements_are_errors_and_unsupported_ones_warnings() {
    assert_eq!(
        message(&format!("{HEAD}usemt grey\nf 1 2 3\n"), MTL),
        "t.obj:7: 'usemt' is not an OBJ statement (v, vt, vn, f, usemtl, mtllib, o, g, s, ...)"
    );
    let scene = parse_with(&format!("{HEAD}l 1 2\nf 1 2 3\ncurv 0 1 1 2\n"), MTL).unwrap();
    assert_eq!(
        scene.warnings,
        ["t.obj: ignored unsupported statement(s): 'l', 'curv'"]
    );
}

#[test]
fn a_library_named_many_times_is_read_once() {
    let mut reads = 0;
    let obj = format!("{}{HEAD}f 1 2 3\n", "mtllib t.mtl\n".repeat(1000));
    let scene = parse_bytes(
        "t",
        Path::new("t.obj"),
        obj.as_bytes(),
        &Limits::default(),
        &mut |_| {
            reads += 1;
            Ok((PathBuf::from("t.mtl"), MTL.as_bytes().to_vec()))
        },
    );
    assert!(scene.is_ok());
    assert_eq!(reads, 1);
}

#[test]
fn collinear_corner_is_removed() {
    let obj =
        "mtllib t.mtl\nv 0 0 0\nv 0.5 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl light\nf 1 2 3 4 5\n";
    let scene = parse_with(obj, MTL).unwrap();
    assert_eq!(scene.surfaces[0].polygon.len(), 4);
}

#[test]
fn continuation_lines_join() {
    let obj = format!("{HEAD}f 1 2 \\\n 3 \\\r\n4\n");
    let scene = parse_with(&obj, MTL).unwrap();
    assert_eq!(scene.surfaces[0].polygon.len(), 4);
}
