//! Property tests of the OBJ grammar: a valid scene
//! written in any formatting the format allows (white space, CRLF or CR
//! line ends, comments, backslash continuations, every vertex-reference
//! form, negative indices, number spellings) loads to exactly the geometry
//! of its plain spelling; and random mutations of a valid file either load
//! or fail with an error naming the file, never panic.

mod common;

use std::path::{Path, PathBuf};

use common::rng::Rng;
use proptest::prelude::*;
use radiosity::scene::obj;
use radiosity::scene::{Limits, Scene, SceneError};

const MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 10 10 10\nnewmtl grey\nKd 0.3 0.6 0.2\n";

fn load(text: &[u8], limits: &Limits) -> Result<Scene, SceneError> {
    obj::parse_bytes("t", Path::new("t.obj"), text, limits, &mut |name: &str| {
        if name == "t.mtl" {
            Ok((PathBuf::from("t.mtl"), MTL.as_bytes().to_vec()))
        } else {
            Err(SceneError::NotFound(name.into()))
        }
    })
}

/// A face: its corners and whether it uses the light.
#[derive(Clone, Debug)]
struct Face {
    corners: Vec<[f64; 3]>,
    light: bool,
}

/// Convex faces (triangles, and quads on a plane) with coordinates on a
/// grid of quarter units, so that every spelling of a number parses to the
/// same bits.
fn face() -> impl Strategy<Value = Face> {
    let coordinate = || (-20i32..20).prop_map(|q| f64::from(q) / 4.0);
    let point = || [coordinate(), coordinate(), coordinate()];
    prop_oneof![
        (point(), point(), point(), any::<bool>()).prop_map(|(a, b, c, light)| Face {
            corners: vec![a, b, c],
            light
        }),
        (point(), 1i32..8, 1i32..8, any::<bool>()).prop_map(|(o, w, h, light)| {
            let (w, h) = (f64::from(w) / 4.0, f64::from(h) / 4.0);
            Face {
                corners: vec![
                    o,
                    [o[0] + w, o[1], o[2]],
                    [o[0] + w, o[1] + h, o[2]],
                    [o[0], o[1] + h, o[2]],
                ],
                light,
            }
        }),
    ]
}

/// The plain spelling: one vertex per corner, positive indices.
fn plain(faces: &[Face]) -> String {
    let mut text = String::from("mtllib t.mtl\n");
    let mut count = 0;
    for f in faces {
        for c in &f.corners {
            text += &format!("v {} {} {}\n", c[0], c[1], c[2]);
        }
        text += if f.light {
            "usemtl light\n"
        } else {
            "usemtl grey\n"
        };
        let refs: Vec<String> = (0..f.corners.len())
            .map(|i| (count + i + 1).to_string())
            .collect();
        text += &format!("f {}\n", refs.join(" "));
        count += f.corners.len();
    }
    text
}

/// The same scene in a random spelling.
fn fancy(faces: &[Face], seed: u64) -> String {
    let mut r = Rng(seed);
    let mut lines: Vec<String> = Vec::new();
    let gap = |r: &mut Rng| r.pick(&[" ", "  ", "\t", " \t "]).to_string();
    let number = |r: &mut Rng, v: f64| match r.below(4) {
        0 => format!("{v}"),
        1 => format!("{v:e}"),
        2 => format!("{v:.6}"),
        _ => format!("{v:+}"),
    };
    lines.push(format!("{}mtllib{}t.mtl", gap(&mut r), gap(&mut r)));
    lines.push("vt 0 0".into());
    lines.push("vt 1 0.5".into());
    lines.push("vn 0 0 1".into());
    let mut count = 0usize;
    for f in faces {
        for c in &f.corners {
            let mut line = String::from("v");
            for v in c {
                line += &gap(&mut r);
                line += &number(&mut r, *v);
            }
            lines.push(line);
        }
        if r.below(3) == 0 {
            lines.push(format!("# a comment {}", r.below(1000)));
        }
        let name = if f.light { "light" } else { "grey" };
        lines.push(format!("usemtl{}{name}", gap(&mut r)));
        let mut line = String::from("f");
        for i in 0..f.corners.len() {
            let index = count + i + 1;
            let v = if r.below(2) == 0 {
                index.to_string()
            } else {
                // Negative: relative to the vertices defined so far.
                format!("-{}", count + f.corners.len() - index + 1)
            };
            let reference = match r.below(4) {
                0 => v,
                1 => format!("{v}/{}", 1 + r.below(2)),
                2 => format!("{v}//1"),
                _ => format!("{v}/-{}/-1", 1 + r.below(2)),
            };
            line += &gap(&mut r);
            if r.below(4) == 0 {
                line += "\\\n";
            }
            line += &reference;
        }
        if r.below(3) == 0 {
            line += " # trailing comment";
        }
        lines.push(line);
        count += f.corners.len();
    }
    let mut text = String::new();
    for line in lines {
        let indent = if r.below(4) == 0 {
            gap(&mut r)
        } else {
            String::new()
        };
        let end = r.pick(&["\n", "\r\n", "\r"]);
        // A continuation inside a line keeps the file's kind of line end.
        text += &indent;
        text += &line.replace("\\\n", &format!("\\{end}"));
        text += end;
        if r.below(6) == 0 {
            text += end;
        }
    }
    text
}

fn same_geometry(a: &Scene, b: &Scene) -> bool {
    a.surfaces.len() == b.surfaces.len()
        && a.surfaces.iter().zip(&b.surfaces).all(|(s, t)| {
            s.polygon == t.polygon && s.rho == t.rho && s.emission == t.emission && s.face == t.face
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_spelling_loads_to_the_same_geometry(
        faces in prop::collection::vec(face(), 1..10),
        seed in any::<u64>(),
    ) {
        let mut faces = faces;
        faces[0].light = true;
        let reference = load(plain(&faces).as_bytes(), &Limits::default());
        let spelled = fancy(&faces, seed);
        let loaded = load(spelled.as_bytes(), &Limits::default());
        match (&reference, &loaded) {
            (Ok(a), Ok(b)) => prop_assert!(same_geometry(a, b), "{spelled:?}"),
            // Only a scene whose faces all have no area fails, and both
            // spellings say so.
            (Err(a), Err(b)) => {
                prop_assert!(a.to_string().contains("degenerate"), "{a}");
                prop_assert_eq!(a.to_string(), b.to_string());
            }
            _ => prop_assert!(false, "{reference:?} vs {loaded:?} for {spelled:?}"),
        }
    }

    #[test]
    fn mutated_files_load_or_fail_with_an_error(
        faces in prop::collection::vec(face(), 1..6),
        seed in any::<u64>(),
        edits in prop::collection::vec((any::<u16>(), 0u8..4, any::<u8>()), 1..8),
    ) {
        let mut bytes = fancy(&faces, seed).into_bytes();
        // Bytes that matter to the grammar, and any byte at all.
        let alphabet = b"0123456789-+./ \t\r\n\\#eEfvtnx\xEF\xBB\xBF\x00\xFF";
        for (position, kind, value) in edits {
            let at = usize::from(position) % (bytes.len() + 1);
            let byte = if value < 128 { alphabet[usize::from(value) % alphabet.len()] } else { value };
            match kind {
                0 => bytes.insert(at, byte),
                1 if at < bytes.len() => { bytes.remove(at); }
                2 if at < bytes.len() => bytes[at] = byte,
                _ => {
                    let end = (at + usize::from(value) % 16).min(bytes.len());
                    let chunk = bytes[at..end].to_vec();
                    bytes.splice(at..at, chunk);
                }
            }
        }
        let limits = Limits { max_corners: 64, max_faces: 64, max_vertices: 256, ..Limits::default() };
        if let Err(e) = load(&bytes, &limits) {
            let message = e.to_string();
            prop_assert!(message.starts_with("t.obj") || message.starts_with("t.mtl") || message.starts_with('\''), "{message}");
            prop_assert!(message.len() < 600, "{message}");
        }
    }
}
