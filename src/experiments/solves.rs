//! The experiments that run the solver: Figure 2.1 (one subsource shot with
//! and without the pre-test), Figure 5.1 (the room's pictures) and
//! Figure 5.2 (solve times).

use super::{Context, Error, Report};

/// Figure 2.1.
pub fn fig2_1(_context: &Context) -> Result<Report, Error> {
    Ok(Report::default())
}

/// Figure 5.1.
pub fn fig5_1(_context: &Context) -> Result<Report, Error> {
    Ok(Report::default())
}

/// Figure 5.2.
pub fn fig5_2(_context: &Context) -> Result<Report, Error> {
    Ok(Report::default())
}
