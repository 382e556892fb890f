//! The built-in scenes, kept as OBJ + MTL files under `scenes/` in the
//! repository and embedded in the binary so `radiosity` works from any
//! folder: `room`, a furnished room after the paper's Figure 5.1,
//! `cornell`, the Cornell box from Cornell's published measurements, and
//! `tworooms`, two rooms joined by a doorway (all light in the second is
//! indirect).

use std::path::{Path, PathBuf};

use super::{Location, Scene, SceneError, obj};

/// One embedded scene.
struct Builtin {
    name: &'static str,
    description: &'static str,
    obj: &'static str,
    mtl_name: &'static str,
    mtl: &'static str,
}

const BUILTINS: [Builtin; 3] = [
    Builtin {
        name: "room",
        description: "a furnished room after the paper's Figure 5.1 (ceiling lights of several sizes)",
        obj: include_str!("../../scenes/room.obj"),
        mtl_name: "room.mtl",
        mtl: include_str!("../../scenes/room.mtl"),
    },
    Builtin {
        name: "cornell",
        description: "the Cornell box from Cornell's published measurements, with its camera",
        obj: include_str!("../../scenes/cornell.obj"),
        mtl_name: "cornell.mtl",
        mtl: include_str!("../../scenes/cornell.mtl"),
    },
    Builtin {
        name: "tworooms",
        description: "two rooms joined by a doorway, the second lit only through it",
        obj: include_str!("../../scenes/tworooms.obj"),
        mtl_name: "tworooms.mtl",
        mtl: include_str!("../../scenes/tworooms.mtl"),
    },
];

/// Names of the built-in scenes.
#[must_use]
pub fn names() -> Vec<&'static str> {
    BUILTINS.iter().map(|b| b.name).collect()
}

/// `(name, description)` of every built-in scene.
#[must_use]
pub fn list() -> Vec<(&'static str, &'static str)> {
    BUILTINS.iter().map(|b| (b.name, b.description)).collect()
}

/// The OBJ text, the MTL library's file name and the MTL text of a
/// built-in scene, as shipped under `scenes/`: to hand the scene to tools
/// that read files (the reference harness of `radiosity experiment
/// validate`).
#[must_use]
pub fn files(name: &str) -> Option<(&'static str, &'static str, &'static str)> {
    BUILTINS
        .iter()
        .find(|b| b.name == name)
        .map(|b| (b.obj, b.mtl_name, b.mtl))
}

/// Loads a built-in scene by name; `None` if there is none of that name.
#[must_use]
pub fn load(name: &str) -> Option<Result<Scene, SceneError>> {
    let builtin = BUILTINS.iter().find(|b| b.name == name)?;
    let path = PathBuf::from(format!("<built-in>/{}.obj", builtin.name));
    Some(obj::parse(
        builtin.name,
        &path,
        builtin.obj,
        &mut |lib: &str| {
            if lib == builtin.mtl_name {
                Ok((
                    PathBuf::from(format!("<built-in>/{lib}")),
                    builtin.mtl.to_string(),
                ))
            } else {
                Err(SceneError::Io {
                    location: Location::file(Path::new(lib)),
                    source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
                })
            }
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_loads_cleanly_with_an_emitter_and_camera() {
        for name in names() {
            let scene = load(name).expect("listed").expect("loads");
            assert!(scene.warnings.is_empty(), "{name}: {:?}", scene.warnings);
            assert!(scene.surfaces.iter().any(|s| s.is_emitter()), "{name}");
            assert!(scene.camera.is_some(), "{name}");
        }
    }
}
