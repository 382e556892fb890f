//! The shared Radiance reference harness (`../shared/reference`: Radiance
//! 6.0a's `rtrace` driven as a path tracer, cross-checked with Mitsuba 3 and
//! closed forms) as the experiments `validate` and `accuracy-curve` use it:
//! finding it and its Python, scoring a vertices CSV with its own
//! `score.py`, and timing plain `rtrace -I` runs at the same points.
//!
//! Every score comes from `score.py` itself, run in-process by a small
//! helper (`tools/reference_score.py`, embedded and written beside the
//! outputs), so the sample of 600 vertices, the cached reference and the
//! numbers are the harness's. [`score`] does the same arithmetic here
//! (L1, bias, median and 90th percentile of the relative error, as
//! `score.py` defines them) for the per-point errors the pictures show, and
//! each score is checked to agree with `score.py`'s own to 1e-9.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::DVec3;

use super::{Context, Error, write_file};

/// The helper script, written next to the outputs when it is run.
const HELPER: &str = include_str!("../../../tools/reference_score.py");

/// The harness's extension to lights that are not surfaces (point, spot
/// and sun lights, skies), written beside the helper when a scene needs it.
const LIGHTS: &str = include_str!("../../../tools/reference_lights.py");

/// `tools/reference_edges.py`: the harness's reference.py with points on
/// a face's edge moved off that edge (see its text), written beside the
/// helper for [`Harness::score_edges`].
const EDGES: &str = include_str!("../../../tools/reference_edges.py");

/// The harness folder looked for when none is given, relative to the
/// working directory and to the source tree (beside a clone, or two levels
/// up from a worktree under `wt/`).
const DEFAULT_HARNESS: [&str; 2] = ["../shared/reference", "../../shared/reference"];

/// The shared scenes' folder looked for when none is given.
const DEFAULT_SCENES: [&str; 2] = ["../shared/scenes", "../../shared/scenes"];

/// The reference harness and the Python that runs it.
#[derive(Clone, Debug)]
pub struct Harness {
    /// The folder holding `score.py`, `reference.py`, `obj2rad.py` and
    /// `setup.sh`.
    pub dir: PathBuf,
    /// The venv's Python (`/tmp/refvenv/bin/python`, which `score.py`
    /// itself calls), with pyradiance and numpy.
    pub python: PathBuf,
    /// Where the helper script is written.
    helper: PathBuf,
}

/// What `score.py` found for one vertices CSV.
#[derive(Clone, Debug)]
pub struct Scored {
    /// The rows of the CSV it sampled (sorted).
    pub rows: Vec<usize>,
    /// Reference radiosity at each sampled row (`None`: the harness matched
    /// no face there).
    pub reference: Vec<Option<DVec3>>,
    /// `score.py`'s L1, bias, median and p90 (fractions).
    pub l1: f64,
    /// Summed bias.
    pub bias: f64,
    /// Median relative error of the bright points.
    pub median: f64,
    /// 90th percentile of the same.
    pub p90: f64,
    /// Points scored.
    pub points: usize,
    /// `score.py`'s rough noise floor of the reference.
    pub noise: f64,
    /// Seconds the reference took to compute (from its cached header),
    /// whenever it was computed.
    pub reference_seconds: Option<f64>,
}

/// One `rtrace -I` run at the sampled points.
#[derive(Clone, Debug)]
pub struct RadianceRun {
    /// Name in the tables.
    pub name: String,
    /// The rtrace options.
    pub options: String,
    /// Wall time of the rtrace call alone.
    pub seconds: f64,
    /// `B = Ke + Kd E` at each point.
    pub radiosity: Vec<DVec3>,
}

/// Rows `score.py` samples from a CSV by default.
pub const SAMPLE: usize = 600;

/// The arithmetic of `score.py` on radiosities `b` against `reference` at
/// the same points.
#[derive(Clone, Debug, PartialEq)]
pub struct Score {
    /// `sum |B - Bref| / sum Bref` of the channel means.
    pub l1: f64,
    /// `sum B / sum Bref - 1`.
    pub bias: f64,
    /// Median of `|B / Bref - 1|` over the bright points (`Bref` above 2%
    /// of its 95th percentile).
    pub median: f64,
    /// 90th percentile of the same.
    pub p90: f64,
    /// Points with a reference.
    pub points: usize,
    /// Signed `B / Bref - 1` of each point; `None` where the reference is
    /// missing or the point is not bright (left out of the median).
    pub relative: Vec<Option<f64>>,
}

/// `numpy.percentile(values, q)` with its default (linear) interpolation.
#[must_use]
pub fn percentile(values: &[f64], q: f64) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    if n == 0 {
        return f64::NAN;
    }
    let position = q / 100.0 * (n - 1) as f64;
    let below = position.floor() as usize;
    let above = (below + 1).min(n - 1);
    let t = position - below as f64;
    let (a, b) = (sorted[below], sorted[above]);
    // numpy's `_lerp`: exact at both ends.
    if t >= 0.5 {
        b - (b - a) * (1.0 - t)
    } else {
        a + (b - a) * t
    }
}

/// Scores radiosities against a reference as `score.py` does.
#[must_use]
pub fn score(b: &[DVec3], reference: &[Option<DVec3>]) -> Score {
    let mean = |v: DVec3| (v.x + v.y + v.z) / 3.0;
    let pairs: Vec<(usize, f64, f64)> = b
        .iter()
        .zip(reference)
        .enumerate()
        .filter_map(|(i, (b, r))| r.map(|r| (i, mean(*b), mean(r))))
        .collect();
    let sum_ref: f64 = pairs.iter().map(|p| p.2).sum();
    let l1 = pairs.iter().map(|p| (p.1 - p.2).abs()).sum::<f64>() / sum_ref;
    let bias = pairs.iter().map(|p| p.1).sum::<f64>() / sum_ref - 1.0;
    let refs: Vec<f64> = pairs.iter().map(|p| p.2).collect();
    let bright_floor = 0.02 * percentile(&refs, 95.0);
    let mut relative = vec![None; b.len()];
    let mut magnitudes = Vec::new();
    for &(i, bm, rm) in &pairs {
        if rm > bright_floor {
            let r = bm / rm - 1.0;
            relative[i] = Some(r);
            magnitudes.push(r.abs());
        }
    }
    Score {
        l1,
        bias,
        median: percentile(&magnitudes, 50.0),
        p90: percentile(&magnitudes, 90.0),
        points: pairs.len(),
        relative,
    }
}

impl Score {
    /// Checks that this score is `score.py`'s own, to round-off.
    pub fn check_against(&self, scored: &Scored, what: &str) -> Result<(), Error> {
        let pairs = [
            ("L1", self.l1, scored.l1),
            ("bias", self.bias, scored.bias),
            ("median", self.median, scored.median),
            ("p90", self.p90, scored.p90),
        ];
        for (name, ours, theirs) in pairs {
            if (ours - theirs).abs() > 1e-9 * theirs.abs().max(1e-3) {
                return Err(Error::Experiment(format!(
                    "{what}: the {name} computed here ({ours}) differs from score.py's ({theirs})"
                )));
            }
        }
        if self.points != scored.points {
            return Err(Error::Experiment(format!(
                "{what}: {} points scored here, {} by score.py",
                self.points, scored.points
            )));
        }
        Ok(())
    }
}

/// The repository's root (the workspace), which the default folders
/// of the shared scenes and the reference are also looked for from.
pub(crate) fn source_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The first of `candidates` (relative to the working directory, then to
/// the source tree) that holds `file`.
fn find_folder(
    given: Option<&Path>,
    candidates: &[&str],
    file: &str,
) -> Result<PathBuf, Vec<PathBuf>> {
    let folders: Vec<PathBuf> = match given {
        Some(dir) => vec![dir.to_path_buf()],
        None => candidates
            .iter()
            .flat_map(|c| [PathBuf::from(c), source_root().join(c)])
            .collect(),
    };
    folders
        .iter()
        .find(|f| f.join(file).is_file())
        .cloned()
        .ok_or(folders)
}

/// The folders looked in, for an error message: `a nor in b`.
pub(crate) fn nor_in(looked: &[PathBuf]) -> String {
    looked
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(" nor in ")
}

/// A file of the shared scenes (`--scenes DIR`, or `../shared/scenes`).
pub fn shared_scene(context: &Context, relative: &str) -> Result<PathBuf, Error> {
    find_folder(context.scenes.as_deref(), &DEFAULT_SCENES, relative)
        .map(|folder| folder.join(relative))
        .map_err(|looked| {
            Error::Experiment(format!(
                "the shared scene {relative} is not in {}: give the folder holding it with \
                 --scenes DIR",
                nor_in(&looked)
            ))
        })
}

impl Harness {
    /// Finds the harness (`--reference DIR`, or `../shared/reference`) and
    /// checks its Python environment.
    pub fn find(context: &Context) -> Result<Harness, Error> {
        let dir = find_folder(context.reference.as_deref(), &DEFAULT_HARNESS, "score.py").map_err(
            |looked| {
                Error::Experiment(format!(
                    "the Radiance reference harness (score.py, reference.py) is not in {}: give \
                     its folder with --reference DIR",
                    nor_in(&looked)
                ))
            },
        )?;
        let dir = dir.canonicalize().unwrap_or(dir);
        // score.py runs reference.py with this interpreter, whatever the
        // environment says.
        Harness::with_python(context, &dir, Path::new("/tmp/refvenv/bin/python"))
    }

    /// The harness in `dir` run by `python`, which must import pyradiance
    /// and numpy.
    pub fn with_python(context: &Context, dir: &Path, python: &Path) -> Result<Harness, Error> {
        let usable = Command::new(python)
            .args(["-c", "import pyradiance, numpy"])
            .output()
            .is_ok_and(|o| o.status.success());
        if !usable {
            return Err(Error::Experiment(format!(
                "the reference harness needs its Python environment ({} with pyradiance and \
                 numpy), which is missing: install it with `bash {}` (a few minutes, from PyPI)",
                python.display(),
                dir.join("setup.sh").display()
            )));
        }
        Ok(Harness {
            dir: dir.to_path_buf(),
            python: python.to_path_buf(),
            helper: context.path("reference_score.py"),
        })
    }

    /// Runs the helper with `args`; its JSON answer is written to `json`.
    fn helper(&self, args: &[&std::ffi::OsStr], json: &Path) -> Result<serde_json::Value, Error> {
        if !self.helper.is_file() {
            write_file(&self.helper, HELPER.as_bytes())?;
        }
        let output = Command::new(&self.python)
            .arg(&self.helper)
            .args(args)
            .output()
            .map_err(|e| Error::Experiment(format!("cannot run {}: {e}", self.python.display())))?;
        if !output.status.success() {
            let stderr = String::from_utf8_lossy(&output.stderr);
            let tail: Vec<&str> = stderr.lines().rev().take(6).collect();
            return Err(Error::Experiment(format!(
                "the reference harness failed: {}",
                tail.into_iter().rev().collect::<Vec<_>>().join(" / ")
            )));
        }
        let text = std::fs::read_to_string(json).map_err(|e| {
            Error::Experiment(format!(
                "{}: the helper wrote no answer: {e}",
                json.display()
            ))
        })?;
        serde_json::from_str(&text)
            .map_err(|e| Error::Experiment(format!("{}: not JSON: {e}", json.display())))
    }

    /// [`Harness::score`] of a scene lit by its surfaces alone.
    pub fn score_lit(
        &self,
        scene: &Path,
        csv: &Path,
        accuracy: &str,
        json: &Path,
    ) -> Result<Scored, Error> {
        self.score(scene, csv, accuracy, json, None)
    }

    /// Scores a vertices CSV of `scene` with `score.py` (computing and
    /// caching the reference at its sample when it is new: minutes). A
    /// scene with lights that are not surfaces gives `lights`, the daylight
    /// flags of its solve (possibly empty): its reference is then computed
    /// by `tools/reference_lights.py` with them.
    pub fn score(
        &self,
        scene: &Path,
        csv: &Path,
        accuracy: &str,
        json: &Path,
        lights: Option<&str>,
    ) -> Result<Scored, Error> {
        self.score_rows(scene, csv, accuracy, json, lights, SAMPLE)
    }

    /// [`Harness::score`] of `n` rows of the CSV (all of them when it has
    /// no more), not `score.py`'s default 600.
    pub fn score_rows(
        &self,
        scene: &Path,
        csv: &Path,
        accuracy: &str,
        json: &Path,
        lights: Option<&str>,
        n: usize,
    ) -> Result<Scored, Error> {
        let script = lights.map(|flags| ("reference_lights.py", LIGHTS, flags));
        self.score_by(scene, csv, accuracy, json, script, n)
    }

    /// [`Harness::score_lit`] with the reference computed by
    /// `tools/reference_edges.py` (cached apart): reference.py with points
    /// on an edge of their face moved off that edge, where reference.py
    /// can leave them within Radiance's 1e-6 m of a surface meeting the
    /// edge and read 35-40% low.
    pub fn score_edges(
        &self,
        scene: &Path,
        csv: &Path,
        accuracy: &str,
        json: &Path,
    ) -> Result<Scored, Error> {
        self.score_by(
            scene,
            csv,
            accuracy,
            json,
            Some(("reference_edges.py", EDGES, "")),
            SAMPLE,
        )
    }

    /// Scores with the reference computed by `script` (file name, text,
    /// flags) in place of reference.py, or by reference.py itself.
    fn score_by(
        &self,
        scene: &Path,
        csv: &Path,
        accuracy: &str,
        json: &Path,
        script: Option<(&str, &str, &str)>,
        n: usize,
    ) -> Result<Scored, Error> {
        let n = n.to_string();
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "score".as_ref(),
            self.dir.as_os_str(),
            scene.as_os_str(),
            csv.as_os_str(),
            json.as_os_str(),
            "--accuracy".as_ref(),
            accuracy.as_ref(),
            "--n".as_ref(),
            n.as_ref(),
        ];
        // One word, `=` joined: the flags start with dashes.
        let flags = script.map(|(_, _, f)| format!("--lights-args={f}"));
        let path = script.map(|(name, _, _)| self.helper.with_file_name(name));
        if let (Some((_, text, _)), Some(flags), Some(path)) = (script, &flags, &path) {
            write_file(path, text.as_bytes())?;
            args.extend(["--lights-script".as_ref(), path.as_os_str(), flags.as_ref()]);
        }
        let value = self.helper(&args, json)?;
        let bad = || Error::Experiment(format!("{}: unexpected answer", json.display()));
        let number = |key: &str| value[key].as_f64().ok_or_else(bad);
        let rows = value["idx"]
            .as_array()
            .ok_or_else(bad)?
            .iter()
            .map(|v| v.as_u64().map(|i| i as usize).ok_or_else(bad))
            .collect::<Result<Vec<_>, _>>()?;
        let reference = value["bref"]
            .as_array()
            .ok_or_else(bad)?
            .iter()
            .map(|v| {
                if v.is_null() {
                    return Ok(None);
                }
                let c: Vec<f64> = v
                    .as_array()
                    .ok_or_else(bad)?
                    .iter()
                    .filter_map(serde_json::Value::as_f64)
                    .collect();
                if c.len() == 3 {
                    Ok(Some(DVec3::new(c[0], c[1], c[2])))
                } else {
                    Err(bad())
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        let reference_seconds = value["reference_header"].as_array().and_then(|lines| {
            lines.iter().filter_map(|l| l.as_str()).find_map(|l| {
                let after = l.split("total ").nth(1)?;
                after.split('s').next()?.parse::<f64>().ok()
            })
        });
        Ok(Scored {
            rows,
            reference,
            l1: number("l1")?,
            bias: number("bias")?,
            median: number("median")?,
            p90: number("p90")?,
            points: value["points"].as_u64().ok_or_else(bad)? as usize,
            noise: number("noise")?,
            reference_seconds,
        })
    }

    /// Times `rtrace -I` with each `(name, options)` of `runs` at `points`
    /// (`(position, normal, input face)`), on `procs` processes.
    pub fn radiance(
        &self,
        scene: &Path,
        points: &[(DVec3, DVec3, u32)],
        runs: &[(String, String)],
        procs: usize,
        work: &Path,
    ) -> Result<Vec<RadianceRun>, Error> {
        let mut text = String::new();
        for (p, n, face) in points {
            text.push_str(&format!(
                "{} {} {} {} {} {} {face}\n",
                p.x, p.y, p.z, n.x, n.y, n.z
            ));
        }
        let points_path = work.with_extension("pts");
        write_file(&points_path, text.as_bytes())?;
        let json = work.with_extension("json");
        let procs = procs.to_string();
        let specs: Vec<String> = runs.iter().map(|(n, o)| format!("{n}|{o}")).collect();
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "radiance".as_ref(),
            self.dir.as_os_str(),
            scene.as_os_str(),
            points_path.as_os_str(),
            json.as_os_str(),
            "--procs".as_ref(),
            procs.as_ref(),
        ];
        args.extend(specs.iter().map(|s| std::ffi::OsStr::new(s.as_str())));
        let value = self.helper(&args, &json)?;
        let bad = || Error::Experiment(format!("{}: unexpected answer", json.display()));
        value["runs"]
            .as_array()
            .ok_or_else(bad)?
            .iter()
            .map(|run| {
                let radiosity = run["b"]
                    .as_array()
                    .ok_or_else(bad)?
                    .iter()
                    .map(|v| {
                        let c: Vec<f64> = v
                            .as_array()
                            .ok_or_else(bad)?
                            .iter()
                            .map(|x| x.as_f64().unwrap_or(f64::NAN))
                            .collect();
                        (c.len() == 3)
                            .then(|| DVec3::new(c[0], c[1], c[2]))
                            .ok_or_else(bad)
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Ok(RadianceRun {
                    name: run["name"].as_str().ok_or_else(bad)?.to_string(),
                    options: run["options"].as_str().ok_or_else(bad)?.to_string(),
                    seconds: run["seconds"].as_f64().ok_or_else(bad)?,
                    radiosity,
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_interpolate_as_numpy_does() {
        // numpy.percentile([3, 1, 4, 1, 5], q) for q = 0, 50, 90, 95, 100.
        let v = [3.0, 1.0, 4.0, 1.0, 5.0];
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert_eq!(percentile(&v, 50.0), 3.0);
        assert!((percentile(&v, 90.0) - 4.6).abs() < 1e-15);
        assert!((percentile(&v, 95.0) - 4.8).abs() < 1e-15);
        assert_eq!(percentile(&v, 100.0), 5.0);
        // An even count: the median is the mean of the middle two.
        assert_eq!(percentile(&[1.0, 2.0, 3.0, 4.0], 50.0), 2.5);
    }
}
