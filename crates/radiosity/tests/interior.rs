//! The default camera of scenes that bring none: inside an
//! interior, at eye height along the long axis, seeing walls in every pixel;
//! framing from outside for open scenes.

mod common;

use approx::abs_diff_eq;
use glam::DVec3;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::render::{self, RenderSettings};
use radiosity::scene::{Camera, Scene, Surface, builtin};
use radiosity::view::{camera_or_framing, interior};

/// The six faces of the box `[lo, hi]`, facing inwards (a room) or
/// outwards (a solid block).
fn cuboid(lo: DVec3, hi: DVec3, inward: bool, face: u32) -> Vec<Surface> {
    let s = hi - lo;
    let (x, y, z) = (DVec3::X * s.x, DVec3::Y * s.y, DVec3::Z * s.z);
    // (origin, u, v) with u x v pointing inwards.
    let faces = [
        (lo, z, x),
        (lo + y, x, z),
        (lo, y, z),
        (lo + x, z, y),
        (lo, x, y),
        (lo + z, y, x),
    ];
    faces
        .iter()
        .enumerate()
        .map(|(k, &(o, u, v))| {
            let (u, v) = if inward { (u, v) } else { (v, u) };
            common::quad(o, u, v, 0.5, 0.0, face + k as u32)
        })
        .collect()
}

/// A light panel facing down just under the ceiling at height `y`.
fn ceiling_light(centre: DVec3, y: f64, side: f64, face: u32) -> Surface {
    let origin = DVec3::new(
        centre.x - 0.5 * side,
        y - 0.01 * side,
        centre.z - 0.5 * side,
    );
    common::quad(origin, DVec3::X * side, DVec3::Z * side, 0.0, 10.0, face)
}

/// A closed room of `size` (metres, or any unit) with a light in the middle
/// of its ceiling.
fn room(size: DVec3) -> Vec<Surface> {
    let mut surfaces = cuboid(DVec3::ZERO, size, true, 0);
    surfaces.push(ceiling_light(0.5 * size, size.y, 0.1 * size.x, 6));
    surfaces
}

/// A picture of the scene from `camera`: the share of its pixels that see
/// a surface.
fn coverage(scene: &Scene, camera: Camera) -> f64 {
    let mesh = Mesh::build(
        scene,
        &MeshSettings {
            patch_size: 1e9,
            element_size: 1e9,
            ..MeshSettings::default()
        },
    )
    .unwrap();
    let colours = vec![DVec3::ONE; mesh.vertices.len()];
    let image = render::render(
        scene,
        &mesh,
        &colours,
        &RenderSettings {
            width: 64,
            height: 48,
            camera,
            supersampling: 1,
        },
    );
    image.coverage.iter().map(|&c| f64::from(c)).sum::<f64>() / image.coverage.len() as f64
}

fn inside(p: DVec3, lo: DVec3, hi: DVec3) -> bool {
    p.cmpgt(lo).all() && p.cmplt(hi).all()
}

fn framing(scene: &Scene) -> Camera {
    let (lo, hi) = scene.bounds();
    Camera::framing(lo, hi)
}

#[test]
fn a_closed_room_is_seen_from_inside_at_eye_height() {
    let size = DVec3::new(8.0, 3.0, 5.0);
    let scene = common::scene_of(room(size));
    let camera = camera_or_framing(&scene);
    assert!(inside(camera.eye, DVec3::ZERO, size), "{camera:?}");
    assert!(
        abs_diff_eq!(camera.eye.y, interior::EYE_HEIGHT, epsilon = 1e-9),
        "{camera:?}"
    );
    // Along the long (x) axis, from near one end towards the other.
    let forward = (camera.target - camera.eye).normalize();
    assert!(forward.x.abs() > 0.95, "{camera:?}");
    let from_end = if forward.x > 0.0 {
        camera.eye.x
    } else {
        size.x - camera.eye.x
    };
    assert!(from_end < 0.5 * size.x, "{camera:?}");
    // Walls, floor and ceiling fill the picture.
    assert!(coverage(&scene, camera) > 0.995);
    assert!(!inside(framing(&scene).eye, DVec3::ZERO, size));
}

#[test]
fn a_room_in_centimetres_puts_the_eye_at_half_height() {
    let size = DVec3::new(800.0, 300.0, 500.0);
    let scene = common::scene_of(room(size));
    let camera = camera_or_framing(&scene);
    assert!(inside(camera.eye, DVec3::ZERO, size), "{camera:?}");
    assert!(
        abs_diff_eq!(camera.eye.y, 150.0, epsilon = 1e-9),
        "{camera:?}"
    );
    assert!(coverage(&scene, camera) > 0.995);
}

#[test]
fn eyes_inside_a_solid_or_facing_a_wall_are_not_chosen() {
    // A 12 m room whose low end is filled by a solid block up to x = 4:
    // the eyes at 10% and 25% of its length from that end are inside it.
    // A partition across the room at x = 6 (both sides) stands right in
    // front of the eyes at 40% from the low end.
    let size = DVec3::new(12.0, 3.0, 4.0);
    let mut surfaces = room(size);
    let e = 0.01;
    surfaces.extend(cuboid(
        DVec3::splat(e),
        DVec3::new(4.0, size.y - e, size.z - e),
        false,
        10,
    ));
    let partition = |x: f64, flip: bool, face: u32| {
        let (u, v) = (DVec3::Y * size.y, DVec3::Z * 3.0);
        let (u, v) = if flip { (v, u) } else { (u, v) };
        common::quad(DVec3::new(x, 0.0, 0.0), u, v, 0.5, 0.0, face)
    };
    surfaces.push(partition(6.0, false, 20));
    surfaces.push(partition(6.0, true, 21));
    let scene = common::scene_of(surfaces);
    let analysis = interior::analyse(&scene).unwrap();
    assert!(analysis.interior);
    for c in &analysis.candidates {
        if c.camera.eye.x < 4.0 {
            assert!(c.back > interior::MAX_BACK, "{c:?}");
            assert!(!c.usable());
        }
    }
    let chosen = &analysis.candidates[analysis.chosen.unwrap()];
    assert!(chosen.camera.eye.x > 6.0, "{chosen:?}");
    assert_eq!(chosen.back, 0.0);
    // The eyes just in front of the partition see less far.
    let blocked = analysis
        .candidates
        .iter()
        .filter(|c| (c.camera.eye.x - 4.8).abs() < 1e-9)
        .map(|c| c.sight)
        .fold(0.0, f64::max);
    assert!(chosen.sight > 1.5 * blocked, "{chosen:?} against {blocked}");
    assert_eq!(camera_or_framing(&scene), chosen.camera);
    assert!(coverage(&scene, chosen.camera) > 0.995);
}

#[test]
fn open_scenes_keep_the_framing_camera() {
    // An object on a ground plane, lit from above.
    let mut surfaces = vec![common::quad(
        DVec3::new(-5.0, 0.0, -5.0),
        DVec3::Z * 10.0,
        DVec3::X * 10.0,
        0.5,
        0.0,
        0,
    )];
    surfaces.extend(cuboid(
        DVec3::new(-1.0, 0.0, -1.0),
        DVec3::new(1.0, 2.0, 1.0),
        false,
        1,
    ));
    surfaces.push(ceiling_light(DVec3::ZERO, 4.0, 1.0, 7));
    let scene = common::scene_of(surfaces);
    let analysis = interior::analyse(&scene).unwrap();
    assert!(!analysis.interior, "escape {}", analysis.escape);
    assert_eq!(camera_or_framing(&scene), framing(&scene));

    // The Cornell box, open at the front, without its camera.
    let mut cornell = builtin::load("cornell").unwrap().unwrap();
    cornell.camera = None;
    let analysis = interior::analyse(&cornell).unwrap();
    assert!(!analysis.interior, "escape {}", analysis.escape);
    assert!(analysis.escape > 3.0 * interior::MAX_ESCAPE);
    assert_eq!(camera_or_framing(&cornell), framing(&cornell));

    // A closed room with no light: nothing to see inside.
    let mut dark = room(DVec3::new(8.0, 3.0, 5.0));
    dark.pop();
    let dark = common::scene_of(dark);
    assert!(interior::analyse(&dark).is_none());
    assert_eq!(camera_or_framing(&dark), framing(&dark));
}

#[test]
fn a_scene_camera_is_kept() {
    let mut scene = common::scene_of(room(DVec3::new(8.0, 3.0, 5.0)));
    let camera = Camera {
        eye: DVec3::new(1.0, 1.0, 1.0),
        target: DVec3::new(2.0, 1.0, 1.0),
        up: DVec3::Y,
        fov_degrees: 40.0,
    };
    scene.camera = Some(camera);
    assert_eq!(camera_or_framing(&scene), camera);
}

/// The shared real scenes: Sponza's atrium and the conference room are
/// interiors, seen from inside; the measured Cornell box (open at the
/// front) is framed.
#[test]
fn shared_scenes() {
    for (file, is_interior) in [
        ("sponza_dabrovic/sponza_dabrovic.obj", true),
        ("conference/conference.obj", true),
        ("cornell_box/cornell_box.obj", false),
    ] {
        let path = common::shared_scene(file);
        let scene = radiosity::scene::load(path.to_str().unwrap()).unwrap();
        let analysis = interior::analyse(&scene).unwrap();
        assert_eq!(
            analysis.interior, is_interior,
            "{file}: {}",
            analysis.escape
        );
        let camera = camera_or_framing(&scene);
        let (lo, hi) = scene.bounds();
        assert_eq!(
            inside(camera.eye, lo, hi),
            is_interior,
            "{file}: {camera:?}"
        );
        if is_interior {
            assert!(coverage(&scene, camera) > 0.99, "{file}");
        }
    }
}
