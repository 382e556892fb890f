//! The form-factor experiments of the paper's section 4: the error tables
//! of Figures 4.2 and 4.6, the colour-scale pictures of Figures 4.3 and 4.5,
//! and the cost of one evaluation of each formula.

use super::{Context, Error, Report};

/// Figures 4.2 and 4.6.
pub fn fig4_2(_context: &Context) -> Result<Report, Error> {
    Ok(Report::default())
}

/// Figures 4.3 and 4.5.
pub fn fig4_3(_context: &Context) -> Result<Report, Error> {
    Ok(Report::default())
}

/// Section 4's timing of 4,140 evaluations.
pub fn formula_timing(_context: &Context) -> Result<Report, Error> {
    Ok(Report::default())
}
