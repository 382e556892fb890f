//! Intel's Embree beside our accelerators in the `rays` experiment (Wong &
//! Tsang 1993, section 3, at the scale of real scenes): the scene's
//! triangles (our convex surfaces fanned), the recorded shadow segments and
//! our answers go into a binary file ([`write_rays`]) that
//! `tools/embree_rays.py`, run with a Python that has the `embreex`
//! package, reads; it times `rtcOccluded1` over the segments with `tfar`
//! the segment's length and prints its time per ray, its build time and its
//! agreement with our answers as JSON.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use glam::DVec3;

use crate::Error;
use radiosity::scene::Scene;

use super::Segment;

/// The Embree benchmark script, written next to its data when it is run.
const EMBREE_SCRIPT: &str = include_str!("../../../../tools/embree_rays.py");

/// The Embree script and its data in a temporary folder, removed on drop.
pub(super) struct EmbreeRun {
    python: PathBuf,
    dir: PathBuf,
}

/// One run of the Embree script.
pub(super) struct EmbreeResult {
    /// Nanoseconds per ray of the timed queries.
    pub(super) ns_per_ray: f64,
    /// Seconds of Embree's build.
    pub(super) build_seconds: f64,
    /// The share of segments on which Embree agrees with our answers.
    pub(super) agreement: f64,
}

impl EmbreeRun {
    /// Writes the script and the scene's triangles, the segments and our
    /// answers ([`write_rays`]) into a new temporary folder.
    pub(super) fn prepare(
        python: &Path,
        name: &str,
        scene: &Scene,
        segments: &[Segment],
        answers: &[bool],
    ) -> Result<EmbreeRun, Error> {
        let dir =
            std::env::temp_dir().join(format!("radiosity-rays-{}-{name}", std::process::id()));
        let output = |source| Error::Output {
            path: std::env::temp_dir(),
            source,
        };
        std::fs::create_dir_all(&dir).map_err(output)?;
        let run = EmbreeRun {
            python: python.to_path_buf(),
            dir,
        };
        std::fs::write(run.dir.join("embree_rays.py"), EMBREE_SCRIPT).map_err(output)?;
        let file = std::fs::File::create(run.dir.join("rays.bin")).map_err(output)?;
        let mut w = std::io::BufWriter::new(file);
        write_rays(&mut w, scene, segments, answers)
            .and_then(|()| w.flush())
            .map_err(output)?;
        Ok(run)
    }

    /// Runs the script once and adds its time per ray and build time to
    /// `timing`; returns its agreement with our answers.
    pub(super) fn time_into(&self, timing: &mut super::Timing) -> Result<f64, Error> {
        let result = self.run()?;
        timing.ns_per_ray.push(result.ns_per_ray);
        timing.build_seconds.push(result.build_seconds);
        Ok(result.agreement)
    }

    /// Runs the script once: it builds Embree's scene and times every
    /// segment.
    pub(super) fn run(&self) -> Result<EmbreeResult, Error> {
        let out = Command::new(&self.python)
            .arg(self.dir.join("embree_rays.py"))
            .arg(self.dir.join("rays.bin"))
            .output()
            .map_err(|e| Error::Experiment(format!("cannot run {}: {e}", self.python.display())))?;
        let text = String::from_utf8_lossy(&out.stdout);
        if !out.status.success() {
            return Err(Error::Experiment(format!(
                "{} tools/embree_rays.py failed: {}",
                self.python.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            )));
        }
        let value: serde_json::Value = serde_json::from_str(text.trim()).map_err(|e| {
            Error::Experiment(format!("tools/embree_rays.py printed {text:?}: {e}"))
        })?;
        let field = |k: &str| {
            value[k].as_f64().ok_or_else(|| {
                Error::Experiment(format!("tools/embree_rays.py gave no {k} in {text:?}"))
            })
        };
        Ok(EmbreeResult {
            ns_per_ray: field("ns_per_ray")?,
            build_seconds: field("build_seconds")?,
            agreement: field("agreement")?,
        })
    }
}

impl Drop for EmbreeRun {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The binary file `tools/embree_rays.py` reads, little-endian:
/// `b"RADRAYS1"`, the triangle count `T` and segment count `S` (`u64`),
/// `T x 9` `f64` triangle corners (each convex surface fanned from its
/// first corner), `S x 6` `f64` segment ends (`from`, `to`), `S` bytes of
/// our answers (1 = blocked).
pub fn write_rays(
    w: &mut impl std::io::Write,
    scene: &Scene,
    segments: &[Segment],
    answers: &[bool],
) -> std::io::Result<()> {
    let triangles: Vec<[DVec3; 3]> = scene
        .surfaces
        .iter()
        .flat_map(|s| {
            let p = &s.polygon;
            (1..p.len() - 1).map(move |i| [p[0], p[i], p[i + 1]])
        })
        .collect();
    w.write_all(b"RADRAYS1")?;
    w.write_all(&(triangles.len() as u64).to_le_bytes())?;
    w.write_all(&(segments.len() as u64).to_le_bytes())?;
    for t in &triangles {
        for p in t {
            for c in p.to_array() {
                w.write_all(&c.to_le_bytes())?;
            }
        }
    }
    for s in segments {
        for c in s.from.to_array().into_iter().chain(s.to.to_array()) {
            w.write_all(&c.to_le_bytes())?;
        }
    }
    let bytes: Vec<u8> = answers.iter().map(|&a| u8::from(a)).collect();
    w.write_all(&bytes)
}
