//! [`Transfer::node_geometry`]'s quadrature against an oracle: each
//! element's exact factor (the paper's equation (2), clipped), summed
//! element by element.

use glam::DVec3;

use super::*;
use crate::accel::Accel;
use crate::scene::{self, merge};
use crate::solver::Settings;
use crate::solver::receiver::vertex_receivers;

/// Runs `check` on a built-in scene as one source, every element sending
/// unit radiosity, with its vertex receivers.
fn with_the_scene_as_source(name: &str, check: impl FnOnce(&Transfer<'_>, &[Receiver])) {
    let mut scene = scene::load(name).unwrap();
    merge::merge_coplanar(&mut scene.surfaces);
    let sizes = scene.default_mesh_sizes();
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = sizes.patch_size;
    settings.mesh.element_size = sizes.element_size;
    let mesh = Mesh::build(&scene, &settings.mesh).unwrap();
    let hierarchy = Hierarchy::build(&scene, &mesh, settings.mesh.patch_size);
    let unshot = vec![DVec3::ONE; mesh.elements.len()];
    let mut sources = Sources::default();
    sources.prepare(&scene, &mesh, &hierarchy, &unshot, 0);
    let occluder = Accel::Bvh.build(&scene.surfaces);
    let transfer = Transfer {
        scene: &scene,
        mesh: &mesh,
        hierarchy: &hierarchy,
        unshot: &unshot,
        sources: &sources,
        root: 0,
        origin: hierarchy.tree.nodes[0].centre,
        occluder: occluder.as_ref(),
        form_factor: FormFactor::Analytic,
    };
    let receivers = vertex_receivers(&scene, &mesh);
    check(&transfer, &receivers);
}

/// The scene's geometry at receiver `r` with error budget `budget`, and
/// the sum of every element's exact factor (unit radiosity, so the first
/// channel is the luminance).
fn geometry_and_exact(
    transfer: &Transfer<'_>,
    r: &Receiver,
    budget: f64,
    scratch: &mut Scratch,
) -> (f64, f64) {
    let mut cost = Cost::default();
    let geometry = transfer
        .node_geometry(0, r, budget, scratch, &mut cost)
        .iter()
        .sum::<DVec3>()
        .x;
    let exact = (0..transfer.mesh.elements.len() as u32)
        .map(|e| transfer.element_factor(e, r, &mut scratch.polygon))
        .sum();
    (geometry, exact)
}

/// A whole scene as one source, every element sending unit radiosity, at
/// every seventh receiver of the scene: the quadrature (corrected point
/// sources for pieces four of their radii away and in front of the
/// receiver's tangent plane, pieces that touch or graze it among them;
/// exact factors near by and across it) against the elements' exact
/// factors. Scenes whose walls stand on their floors, so that the
/// receivers' planes touch many of the pieces.
#[test]
fn node_geometry_matches_the_elements_exact_factors() {
    for name in ["cornell", "room"] {
        with_the_scene_as_source(name, |transfer, receivers| {
            let mut scratch = Scratch::default();
            let (mut worst, mut total_error, mut total) = (0.0f64, 0.0, 0.0);
            for r in receivers.iter().step_by(7) {
                let (quadrature, exact) = geometry_and_exact(transfer, r, 0.0, &mut scratch);
                worst = worst.max((quadrature - exact).abs() / exact);
                total_error += (quadrature - exact).abs();
                total += exact;
            }
            let mean = total_error / total;
            assert!(
                mean < 2e-4,
                "{name}: the quadrature errs by {mean} on average"
            );
            assert!(
                worst < 2e-3,
                "{name}: the quadrature errs by {worst} at worst"
            );
        });
    }
}

/// The same scenes and receivers with an error budget of a thousandth to
/// a tenth of what the scene sends the receiver: the geometry errs by no
/// more than the budget beyond the quadrature's own error, and the
/// budget is used (pieces taken whole that the quadrature would split).
#[test]
fn a_budget_bounds_the_geometry_s_error() {
    for name in ["cornell", "room"] {
        with_the_scene_as_source(name, |transfer, receivers| {
            let mut scratch = Scratch::default();
            for share in [1e-3, 1e-2, 1e-1] {
                let (mut worst, mut changed, mut tested) = (0.0f64, 0, 0);
                for r in receivers.iter().step_by(7) {
                    let (quadrature, exact) = geometry_and_exact(transfer, r, 0.0, &mut scratch);
                    let budget = share * exact;
                    let (budgeted, _) = geometry_and_exact(transfer, r, budget, &mut scratch);
                    let beyond = (budgeted - exact).abs() - (quadrature - exact).abs();
                    worst = worst.max(beyond / budget);
                    changed += usize::from(budgeted != quadrature);
                    tested += 1;
                }
                assert!(
                    worst <= 1.0 + 1e-9,
                    "{name}, budget {share}: errs by {worst} budgets beyond the quadrature"
                );
                assert!(
                    changed * 10 >= tested,
                    "{name}, budget {share}: only {changed} of {tested} receivers used it"
                );
            }
        });
    }
}
