//! What the command-line tests share: a small scene with a hole for one
//! bad line, a folder holding it, the binary run on the CPU, and the check
//! that bad input is refused with one `error:` line and no output.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The materials of [`obj`]'s scene.
pub const MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 10 10 10\nnewmtl white\nKd 0.7 0.7 0.7\n";

/// A floor under a light, with a hole for one bad line.
pub fn obj(extra: &str) -> String {
    format!(
        "mtllib scene.mtl\n\
         v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\n\
         v -0.2 1 -0.2\nv 0.2 1 -0.2\nv 0.2 1 0.2\nv -0.2 1 0.2\n\
         usemtl white\nf 4 3 2 1\nusemtl light\nf 5 6 7 8\n{extra}"
    )
}

/// A scene in a folder of its own.
pub struct Case {
    /// The folder holding `scene.obj` and `scene.mtl`.
    pub dir: tempfile::TempDir,
}

impl Case {
    /// A folder holding `obj` and `mtl` as `scene.obj` and `scene.mtl`.
    pub fn new(obj: &str, mtl: &str) -> Case {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("scene.obj"), obj).unwrap();
        std::fs::write(dir.path().join("scene.mtl"), mtl).unwrap();
        Case { dir }
    }

    /// `name` in the folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// `render` of `scene`, writing a picture and a vertices CSV here.
    pub fn render(&self, scene: &Path) -> Output {
        run(&[
            "render",
            scene.to_str().unwrap(),
            "--output",
            self.path("out.png").to_str().unwrap(),
            "--vertices",
            self.path("out.csv").to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "24",
            "--max-shots",
            "2",
        ])
    }

    /// Nothing was written: no picture, no CSV, no stray temporary file.
    pub fn assert_no_output(&self) {
        let mut names: Vec<String> = std::fs::read_dir(self.dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["scene.mtl", "scene.obj"]);
    }
}

/// The binary on the CPU with `args`.
pub fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env("RADIOSITY_DEVICE", "cpu")
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Runs a bad scene and checks the error: one `error:` line that contains
/// every expected fragment, non-zero exit, no panic, no output.
pub fn assert_rejected(obj_text: &str, mtl: &str, expected: &[&str]) {
    let case = Case::new(obj_text, mtl);
    let out = case.render(&case.path("scene.obj"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "accepted: {stderr}");
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    for fragment in expected {
        assert!(
            errors[0].contains(fragment),
            "'{fragment}' not in: {stderr}"
        );
    }
    case.assert_no_output();
}
