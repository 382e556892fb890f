//! What a solving method holds in memory (beyond the paper), reported by
//! the method itself ([`super::Method::memory`]) for the run's estimate
//! ([`crate::memory::estimate`], which adds every layer's parts): per
//! vertex, element and surface, and lumps of its own.

/// A solving method's own memory: per item, added to the shared parts of
/// those items, and lumps of its own.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverCosts {
    /// Per vertex.
    pub vertex: f64,
    /// Per element.
    pub element: f64,
    /// Per surface.
    pub surface: f64,
    /// Parts of its own that live until the outputs are written.
    pub parts: Vec<Part>,
}

/// One part of an estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// What it is, e.g. `elements`.
    pub name: &'static str,
    /// How many items (1 for a lump).
    pub count: u64,
    /// Bytes each.
    pub each: f64,
    /// The setting that changes it, for messages.
    pub remedy: &'static str,
}

impl Part {
    /// The part's bytes.
    #[must_use]
    pub fn bytes(&self) -> f64 {
        self.count as f64 * self.each
    }
}
