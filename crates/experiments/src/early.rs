//! The scale experiment's early pictures, beyond the paper (whose Figure 5.1
//! shows its room after 9, 48 and 72 subsources, by eye): how far the
//! vertex radiosity a time-limited run writes after 2, 5 and 10 seconds of
//! solve is from the scene's final state, as an L1 error
//! `sum |B - B_final| / sum B_final` over the vertices (the three channels
//! summed), so that `--time-limit` is a choice a user can make knowing what
//! it costs. The final state is the experiment's own run of the scene at
//! its full time limit: converged when that run converged, otherwise the
//! state it reached (said so in the report).

use std::path::Path;

/// Seconds of solve after which the early pictures are taken.
pub const EARLY_SECONDS: [u64; 3] = [2, 5, 10];

/// One early picture: its time limit and its error against the final
/// state.
#[derive(Clone, Debug, PartialEq)]
pub struct Early {
    /// `--time-limit` of the run, seconds.
    pub seconds: u64,
    /// The L1 error of its vertex radiosity against the final state, and
    /// the unshot fraction it had reached; or why it could not be measured
    /// (another mesh: its coarse pass was cut short by the limit).
    pub result: Result<(f64, f64), String>,
    /// Why its solve stopped (`None` when the run failed).
    pub stop_reason: Option<String>,
    /// Why its coarse pass stopped (`None` without one, or when the run
    /// failed): "time limit reached" when the limit cut it short, so its
    /// mesh is not the final state's.
    pub coarse_stop_reason: Option<String>,
}

impl Early {
    /// Whether the limit cut its coarse pass short (its mesh then depends
    /// on how fast the machine was, and may not be the final state's).
    #[must_use]
    pub fn coarse_pass_cut(&self) -> bool {
        self.coarse_stop_reason.as_deref()
            == Some(radiosity::solver::StopReason::TimeLimit.describe())
    }
}

/// Each vertex's radiosity (red, green and blue summed) from a vertices
/// CSV written by `radiosity render --vertices` (`x,y,z,nx,ny,nz,surface,
/// r,g,b`).
///
/// # Errors
///
/// A file that cannot be read, or a row without three numbers after its
/// surface.
pub fn vertex_radiosity(path: &Path) -> Result<Vec<f64>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    if header != "x,y,z,nx,ny,nz,surface,r,g,b" {
        return Err(format!("{}: unexpected header {header:?}", path.display()));
    }
    lines
        .enumerate()
        .map(|(i, line)| {
            let values: Result<Vec<f64>, _> = line.split(',').skip(7).map(str::parse).collect();
            match values {
                Ok(v) if v.len() == 3 => Ok(v.iter().sum()),
                _ => Err(format!(
                    "{}: line {}: not 10 numbers: {line:?}",
                    path.display(),
                    i + 2
                )),
            }
        })
        .collect()
}

/// `sum |a - b| / sum b` over paired values.
///
/// # Errors
///
/// When the two differ in length (two meshes) or the reference sums to
/// zero.
pub fn l1(values: &[f64], reference: &[f64]) -> Result<f64, String> {
    if values.len() != reference.len() {
        return Err(format!(
            "{} vertices against the final state's {}",
            values.len(),
            reference.len()
        ));
    }
    let total: f64 = reference.iter().sum();
    if total <= 0.0 || !total.is_finite() {
        return Err("the final state is dark".into());
    }
    let difference: f64 = values
        .iter()
        .zip(reference)
        .map(|(a, b)| (a - b).abs())
        .sum();
    Ok(difference / total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn l1_of_known_values() {
        assert_eq!(l1(&[1.0, 3.0], &[2.0, 2.0]), Ok(0.5));
        assert_eq!(l1(&[2.0, 2.0], &[2.0, 2.0]), Ok(0.0));
        assert!(l1(&[1.0], &[1.0, 2.0]).is_err());
        assert!(l1(&[1.0], &[0.0]).is_err());
    }

    #[test]
    fn vertex_radiosity_sums_the_channels_and_names_a_bad_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v.csv");
        std::fs::write(
            &path,
            "x,y,z,nx,ny,nz,surface,r,g,b\n0,0,0,0,1,0,3,0.5,0.25,0.25\n1,0,0,0,1,0,3,1,2,3\n",
        )
        .unwrap();
        assert_eq!(vertex_radiosity(&path), Ok(vec![1.0, 6.0]));
        std::fs::write(
            &path,
            "x,y,z,nx,ny,nz,surface,r,g,b\n0,0,0,0,1,0,3,0.5,x,0.25\n",
        )
        .unwrap();
        let error = vertex_radiosity(&path).unwrap_err();
        assert!(error.contains("line 2"), "{error}");
    }
}
