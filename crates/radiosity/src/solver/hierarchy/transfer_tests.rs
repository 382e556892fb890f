//! [`Transfer::node_geometry`]'s quadrature against an oracle: each
//! element's exact factor (the paper's equation (2), clipped), summed
//! element by element.

use glam::DVec3;

use super::*;
use crate::accel::Accel;
use crate::scene::{self, merge};
use crate::solver::Settings;
use crate::solver::receiver::vertex_receivers;

/// A whole scene as one source, every element sending unit radiosity, at
/// every receiver of the scene: the quadrature (corrected point sources
/// for pieces four of their radii away and in front of the receiver's
/// tangent plane, pieces that touch or graze it among them; exact
/// factors near by and across it) against the elements' exact factors.
/// Scenes whose walls stand on their floors, so that the receivers'
/// planes touch many of the pieces.
#[test]
fn node_geometry_matches_the_elements_exact_factors() {
    for name in ["cornell", "room"] {
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
        let (mut scratch, mut cost) = (Scratch::default(), Cost::default());
        let (mut worst, mut total_error, mut total) = (0.0f64, 0.0, 0.0);
        let receivers = vertex_receivers(&scene, &mesh);
        for r in receivers.iter().step_by(7) {
            let quadrature = transfer
                .node_geometry(0, r, &mut scratch, &mut cost)
                .iter()
                .sum::<DVec3>()
                .x;
            let exact: f64 = (0..mesh.elements.len() as u32)
                .map(|e| transfer.element_factor(e, r, &mut scratch.polygon))
                .sum();
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
    }
}
