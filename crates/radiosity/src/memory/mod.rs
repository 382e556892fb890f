//! Memory (beyond the paper): an estimate of a run's peak from the counts
//! known once the scene is meshed, so a run that would exhaust the machine
//! is refused before its solve, naming the setting to change. What the
//! process and the machine hold is read in `probe`, sizes as people write
//! them are parsed in `size`.
//!
//! The model adds, for each kind of item, its count times a cost in bytes
//! measured on the shared scenes with a counting allocator
//! (`examples/memory_costs.rs`; the measurements are in EXPERIMENTS.md,
//! "Memory"):
//!
//! | part | cost |
//! | --- | --- |
//! | process | [`BASE`]: the binary, libraries, thread stacks |
//! | scene | [`SURFACE`] a surface (polygon, plane, material) |
//! | mesh | [`ELEMENT`] an element, [`VERTEX`] a vertex, [`PATCH`] a patch (the structures with their vectors' growth slack) |
//! | accelerator | [`ACCEL`] a surface, BVH or BSP alike |
//! | solver | the method's own ([`crate::solver::Method::memory`]): per vertex (receiver, radiosity, irradiance; patch shooting keeps more per receiver), per element (adaptive shooting's unshot radiosity and cluster hierarchy), per surface (the prepared surfaces of the segment test), and lumps such as the hemicube pre-test's item buffers: [`SolverCosts`] |
//! | last stage | the largest of: a shot's buffers ([`SHOT_VERTEX`] a vertex), the picture (samples at [`SAMPLE`], pixels at [`PIXEL`], [`SCREEN_ELEMENT`] an element projected), the default view's BVH ([`VIEW_SURFACE`] a surface, when the scene brings no camera), the glTF bake ([`BAKE_VERTEX`], [`BAKE_ELEMENT`]), a lightmap bake ([`LIGHTMAP_TEXEL`] a texel), a refinement's coarse pass going on (its mesh and solve, and its lights' kept shots, [`GoingOn`]) |
//!
//! Everything but the last stage lives until the outputs are written, so
//! the peak is their sum plus the largest last stage. On the shared scenes
//! the estimate is within a factor of 1.5 of the measured peak (tested on
//! the built-in scenes and Sponza in `tests/memory.rs`).

use std::fmt;

mod probe;
mod size;

pub use self::probe::{available_bytes, peak_resident_bytes, reset_peak, resident_bytes};
pub use self::size::{SizeError, bytes, parse_size};

pub use crate::solver::costs::{Part, SolverCosts};

/// The process before any scene: binary, libraries, thread stacks, the
/// allocator's arenas. Measured on the release binary (Linux, 2 threads):
/// the peak of the smallest jobs less the rest of their estimate is
/// 10.8 MiB (the Cornell box, one shot, an 8 x 6 picture) to 12.0 MiB (the
/// room, one shot, 64 x 48); it was 6 MiB before the GPU back end and the
/// glTF bakes were linked in.
pub const BASE: u64 = 11 << 20;
/// A loaded surface.
pub const SURFACE: f64 = 310.0;
/// A mesh element.
pub const ELEMENT: f64 = 60.0;
/// A mesh vertex (with its direct part, booked apart).
pub const VERTEX: f64 = 108.0;
/// A mesh patch.
pub const PATCH: f64 = 180.0;
/// The shadow-ray accelerator, per surface.
pub const ACCEL: f64 = 135.0;
/// A shot's buffers, per vertex.
pub const SHOT_VERTEX: f64 = 64.0;
/// The displayed radiosity, per vertex.
pub const DISPLAY_VERTEX: f64 = 24.0;
/// A picture sample (colour and coverage).
pub const SAMPLE: f64 = 13.0;
/// A picture sample's surface point under the final pass, kept from its
/// rasterising until its shading (a triangle and two weights).
pub const SHADED_SAMPLE: f64 = 12.0;
/// A picture pixel (colour and coverage).
pub const PIXEL: f64 = 16.0;
/// An element projected for the picture (two screen triangles, with their
/// world corners for the final pass).
pub const SCREEN_ELEMENT: f64 = 320.0;

/// The final pass ([`crate::final_gather`]), per vertex: the indirect part
/// (`direct`), and the reflected radiosity (`full`).
pub const FINAL_VERTEX: f64 = 48.0;

/// `full`'s index of the element triangles, per element.
pub const FINAL_ELEMENT: f64 = 400.0;
/// The default view's BVH while it is built, per surface
/// ([`crate::view::interior`]).
pub const VIEW_SURFACE: f64 = 625.0;
/// The glTF bake, per vertex (position, normal, colour; built, then
/// staged).
pub const BAKE_VERTEX: f64 = 80.0;
/// The glTF bake, per element (indices).
pub const BAKE_ELEMENT: f64 = 48.0;

/// Bytes a lightmap texel takes at the bake's peak: its claim (32), both
/// sides' values (24), the value (12), the image (12) and the encoded PNG
/// and EXR (about 10).
pub const LIGHTMAP_TEXEL: f64 = 90.0;

/// What a run holds, for the estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sizes {
    /// Input surfaces.
    pub surfaces: u64,
    /// Mesh patches.
    pub patches: u64,
    /// Mesh elements.
    pub elements: u64,
    /// Mesh vertices.
    pub vertices: u64,
    /// Picture samples (pixels times supersampling squared); 0 for none.
    pub samples: u64,
    /// Picture pixels; 0 for none.
    pub pixels: u64,
    /// Whether the default view is computed (no camera given).
    pub view: bool,
    /// Whether a glTF bake is written.
    pub bake: bool,
    /// Texels of a lightmap bake (an upper bound); 0 for none.
    pub lightmap_texels: u64,
    /// The final pass the outputs take.
    pub final_gather: crate::final_gather::FinalGather,
    /// The coarse pass of a refinement that goes on on this (refined)
    /// mesh: its base mesh's counts and the lights whose shots it keeps;
    /// `None` without one.
    pub going_on: Option<GoingOn>,
}

/// The coarse pass a refined solve goes on from
/// ([`crate::solver::Solver::go_on`]): it lives, with its kept shots,
/// until the refined mesh's state is made from it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GoingOn {
    /// Its mesh's elements.
    pub elements: u64,
    /// Its mesh's vertices.
    pub vertices: u64,
    /// Lights it shot, each kept with its irradiance at every vertex and
    /// mean at every element ([`KEPT_LIGHT_ITEM`] each).
    pub lights: u64,
}

/// A light's shot kept for its replay, per vertex and per element.
pub const KEPT_LIGHT_ITEM: f64 = 24.0;

/// An estimate of a run's peak resident memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// Parts that live until the outputs are written.
    pub kept: Vec<Part>,
    /// Alternatives of the last stage; the largest counts.
    pub last: Vec<Part>,
}

impl Estimate {
    /// The estimated peak, bytes.
    #[must_use]
    pub fn total(&self) -> u64 {
        let kept: f64 = self.kept.iter().map(Part::bytes).sum();
        let last = self.last.iter().map(Part::bytes).fold(0.0, f64::max);
        (kept + last).ceil() as u64
    }

    /// The parts that count, largest first.
    #[must_use]
    pub fn parts(&self) -> Vec<&Part> {
        let mut parts: Vec<&Part> = self.kept.iter().collect();
        if let Some(last) = self
            .last
            .iter()
            .max_by(|a, b| a.bytes().total_cmp(&b.bytes()))
        {
            parts.push(last);
        }
        parts.sort_by(|a, b| b.bytes().total_cmp(&a.bytes()));
        parts
    }
}

impl fmt::Display for Estimate {
    /// `about 31.2 GiB (elements 120M at 180 B each, ...)`: the four
    /// largest parts.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self
            .parts()
            .iter()
            .take(4)
            .map(|p| {
                if p.count == 1 {
                    format!("{} {}", p.name, bytes(p.bytes() as u64))
                } else {
                    format!("{} {} at {:.0} B each", p.name, count(p.count), p.each)
                }
            })
            .collect();
        write!(f, "about {} ({})", bytes(self.total()), parts.join(", "))
    }
}

/// Estimates a run's peak from its sizes and its solving method's own
/// costs ([`crate::solver::Method::memory`]).
#[must_use]
pub fn estimate(sizes: &Sizes, solver: SolverCosts) -> Estimate {
    let element_remedy = "raise --element-size";
    let (solver_element, solver_vertex) = (solver.element, solver.vertex);
    let mut kept = vec![
        Part {
            name: "process",
            count: 1,
            each: BASE as f64,
            remedy: "",
        },
        Part {
            name: "surfaces",
            count: sizes.surfaces,
            each: SURFACE + ACCEL + solver.surface,
            remedy: "simplify the scene",
        },
        Part {
            name: "elements",
            count: sizes.elements,
            each: ELEMENT + solver.element,
            remedy: element_remedy,
        },
        Part {
            name: "vertices",
            count: sizes.vertices,
            each: VERTEX + solver.vertex + DISPLAY_VERTEX,
            remedy: element_remedy,
        },
        Part {
            name: "patches",
            count: sizes.patches,
            each: PATCH,
            remedy: "raise --patch-size",
        },
    ];
    kept.extend(solver.parts);
    let mut last = vec![Part {
        name: "shot buffers",
        count: sizes.vertices,
        each: SHOT_VERTEX,
        remedy: element_remedy,
    }];
    if sizes.samples > 0 {
        last.push(Part {
            name: "picture",
            count: 1,
            each: sizes.samples as f64 * SAMPLE
                + sizes.pixels as f64 * PIXEL
                + sizes.elements as f64 * SCREEN_ELEMENT,
            remedy: "lower --width, --height or --supersampling",
        });
    }
    if sizes.view {
        last.push(Part {
            name: "default view",
            count: sizes.surfaces,
            each: VIEW_SURFACE,
            remedy: "give --camera",
        });
    }
    if sizes.bake {
        last.push(Part {
            name: "bake",
            count: 1,
            each: sizes.vertices as f64 * BAKE_VERTEX + sizes.elements as f64 * BAKE_ELEMENT,
            remedy: element_remedy,
        });
    }
    if sizes.final_gather != crate::final_gather::FinalGather::Off
        && (sizes.samples > 0 || sizes.lightmap_texels > 0)
    {
        let full = sizes.final_gather == crate::final_gather::FinalGather::Full;
        kept.push(Part {
            name: "final pass",
            count: 1,
            each: sizes.vertices as f64 * FINAL_VERTEX
                + sizes.samples as f64 * SHADED_SAMPLE
                + if full {
                    sizes.elements as f64 * FINAL_ELEMENT
                } else {
                    0.0
                },
            remedy: "--final-gather off",
        });
    }
    if let Some(coarse) = sizes.going_on {
        // The coarse solve, its kept shots and the state it hands over
        // (the refined mesh's: what the final solve then keeps).
        last.push(Part {
            name: "coarse pass going on",
            count: 1,
            each: coarse.elements as f64 * (ELEMENT + solver_element)
                + coarse.vertices as f64 * (VERTEX + solver_vertex)
                + coarse.lights as f64
                    * (coarse.elements + coarse.vertices) as f64
                    * KEPT_LIGHT_ITEM,
            remedy: element_remedy,
        });
    }
    if sizes.lightmap_texels > 0 {
        last.push(Part {
            name: "lightmap",
            count: sizes.lightmap_texels,
            each: LIGHTMAP_TEXEL,
            remedy: "lower --lightmap-density or --lightmap-max-size",
        });
    }
    Estimate { kept, last }
}

/// Why a run is refused.
#[derive(Clone, Debug, PartialEq)]
pub struct TooLarge {
    /// The estimate.
    pub estimate: Estimate,
    /// What the run may use, bytes.
    pub limit: u64,
    /// Where the limit came from.
    pub source: LimitSource,
}

/// Where a memory limit came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LimitSource {
    /// `--max-memory`.
    Option,
    /// The machine's available memory (MemAvailable) plus what this
    /// process already holds.
    Machine,
}

impl fmt::Display for TooLarge {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut remedies: Vec<&str> = Vec::new();
        for p in self.estimate.parts() {
            if !p.remedy.is_empty() && !remedies.contains(&p.remedy) {
                remedies.push(p.remedy);
            }
            if remedies.len() == 2 {
                break;
            }
        }
        let has = match self.source {
            LimitSource::Option => format!("--max-memory allows {}", bytes(self.limit)),
            LimitSource::Machine => format!("the machine has {} available", bytes(self.limit)),
        };
        let escape = match self.source {
            LimitSource::Option => "raise --max-memory",
            LimitSource::Machine => "give a larger --max-memory to try anyway",
        };
        remedies.push(escape);
        write!(
            f,
            "this run needs {}; {has}: {}",
            self.estimate,
            remedies.join(", or ")
        )
    }
}

/// Checks an estimate against a limit: `limit` if given, else what the
/// machine has available plus what this process already holds (the scene
/// and mesh are resident and counted by the estimate). No limit is known
/// on a system without `/proc/meminfo`: the check passes.
pub fn check(estimate: &Estimate, limit: Option<u64>) -> Result<(), TooLarge> {
    let (limit, source) = match limit {
        Some(limit) => (limit, LimitSource::Option),
        None => match available_bytes() {
            Some(available) => (
                available.saturating_add(resident_bytes().unwrap_or(0)),
                LimitSource::Machine,
            ),
            None => return Ok(()),
        },
    };
    if estimate.total() > limit {
        return Err(TooLarge {
            estimate: estimate.clone(),
            limit,
            source,
        });
    }
    Ok(())
}

/// `120M`, `4.5k`, `17`.
fn count(n: u64) -> String {
    if n >= 10_000_000 {
        format!("{:.0}M", n as f64 / 1e6)
    } else if n >= 1_000_000 {
        format!("{:.1}M", n as f64 / 1e6)
    } else if n >= 10_000 {
        format!("{:.0}k", n as f64 / 1e3)
    } else {
        n.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::Settings;

    /// A run of `elements` and `vertices` that writes nothing drawn.
    fn solve_only(elements: u64, vertices: u64) -> Sizes {
        Sizes {
            surfaces: 0,
            patches: 0,
            elements,
            vertices,
            samples: 0,
            pixels: 0,
            view: false,
            bake: false,
            lightmap_texels: 0,
            final_gather: crate::final_gather::FinalGather::Off,
            going_on: None,
        }
    }

    #[test]
    fn the_estimate_names_its_largest_parts() {
        let sizes = Sizes {
            surfaces: 1_000,
            patches: 1_000,
            ..solve_only(120_000_000, 100_000_000)
        };
        let e = estimate(&sizes, Settings::adaptive().method.method().memory());
        // The shot's buffers are the largest last stage.
        let expected =
            120e6 * (ELEMENT + 294.0) + 100e6 * (VERTEX + 104.0 + DISPLAY_VERTEX + SHOT_VERTEX);
        assert!((e.total() as f64 - expected).abs() / expected < 0.01);
        let text = e.to_string();
        let gib = expected / f64::from(1u32 << 30);
        assert!(
            text.starts_with(&format!(
                "about {gib:.1} GiB (elements 120M at 354 B each, "
            )),
            "{text}"
        );
        let refusal = check(&e, Some(1 << 30)).unwrap_err().to_string();
        assert!(refusal.contains("--max-memory allows 1.0 GiB"), "{refusal}");
        assert!(refusal.contains("raise --element-size"), "{refusal}");
        assert!(check(&e, Some(1 << 40)).is_ok());
    }

    /// A refinement's coarse pass going on is a last stage of its own:
    /// its mesh, its solve and its lights' kept shots, counted when it is
    /// the largest.
    #[test]
    fn the_coarse_pass_going_on_is_counted() {
        let sizes = Sizes {
            surfaces: 10,
            patches: 10,
            ..solve_only(1_000, 1_000)
        };
        let costs = Settings::adaptive().method.method().memory();
        let without = estimate(&sizes, costs.clone());
        let coarse = GoingOn {
            elements: 800,
            vertices: 900,
            lights: 3,
        };
        let with = estimate(
            &Sizes {
                going_on: Some(coarse),
                ..sizes
            },
            costs.clone(),
        );
        let part = with
            .last
            .iter()
            .find(|p| p.name == "coarse pass going on")
            .expect("the part is listed");
        let expected = 800.0 * (ELEMENT + costs.element)
            + 900.0 * (VERTEX + costs.vertex)
            + 3.0 * 1_700.0 * KEPT_LIGHT_ITEM;
        assert!((part.bytes() - expected).abs() < 1e-6);
        // Larger than a shot's buffers here, so it is the last stage.
        assert!(expected > 1_000.0 * SHOT_VERTEX);
        let shot_buffers = 1_000.0 * SHOT_VERTEX;
        // Each total is rounded up to a byte.
        let grown = (with.total() - without.total()) as f64;
        assert!((grown - (expected - shot_buffers)).abs() <= 1.0, "{grown}");
    }
}
