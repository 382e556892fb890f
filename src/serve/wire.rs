//! The binary messages of the live view (layouts in the [module
//! documentation](super)): the element mesh, sent once, and colour frames,
//! sent as the solution changes, carrying only the vertices whose encoded
//! colour changed since the client's previous frame.
//!
//! Colours travel in Ward's shared-exponent RGBE (*Real Pixels*, Graphics
//! Gems II, 1991; Radiance's `.hdr` pixels): four bytes a vertex, about 1%
//! relative precision, and the whole range radiosity can take (2^-128 to
//! 2^127 W/m^2), which neither 8-bit colour nor f16 (largest 65504) has.

use glam::DVec3;

use radiosity::mesh::Mesh;
use radiosity::scene::Scene;

/// First four bytes of the mesh message.
pub const MESH_MAGIC: [u8; 4] = *b"RMSH";
/// First four bytes of a colour frame.
pub const COLOURS_MAGIC: [u8; 4] = *b"RCOL";
/// Flag of a colour frame that lists every vertex in order, without
/// indices.
pub const FLAG_FULL: u32 = 1;

/// Size of a colour frame's header in bytes.
pub const COLOURS_HEADER: usize = 28;

/// One colour in RGBE: three 8-bit mantissas and a biased exponent.
pub type Rgbe = [u8; 4];

/// Encodes a non-negative linear colour as RGBE (Ward 1991): the largest
/// channel `v = m 2^e` with `m` in [0.5, 1) sets the exponent byte `e +
/// 128`, and each channel keeps `floor(c 256 / 2^e)`. Negative, NaN and
/// values below 1e-32 encode as black; values beyond 2^127 saturate.
#[must_use]
pub fn rgbe(colour: DVec3) -> Rgbe {
    let c = colour.to_array().map(|v| if v > 0.0 { v } else { 0.0 });
    let v = c[0].max(c[1]).max(c[2]);
    // NaN became 0 above.
    if v < 1e-32 {
        return [0; 4];
    }
    // Saturate rather than wrap the exponent byte.
    let v_max = (1.0 - f64::EPSILON) * 2f64.powi(127);
    let c = c.map(|x| x.min(v_max));
    let v = v.min(v_max);
    // frexp: v = m 2^e, m in [0.5, 1). v is normal here, so its exponent
    // field is exact.
    let e = ((v.to_bits() >> 52) & 0x7ff) as i32 - 1022;
    let scale = 256.0 / 2f64.powi(e);
    [
        (c[0] * scale) as u8,
        (c[1] * scale) as u8,
        (c[2] * scale) as u8,
        (e + 128) as u8,
    ]
}

/// Decodes RGBE as Radiance does (and the page does): each channel is
/// `(byte + 0.5) 2^(e - 136)`, black when the exponent byte is 0. Only the
/// tests decode on this side.
#[cfg(test)]
#[must_use]
pub fn rgbe_to_rgb(rgbe: Rgbe) -> DVec3 {
    if rgbe[3] == 0 {
        return DVec3::ZERO;
    }
    let f = 2f64.powi(i32::from(rgbe[3]) - 136);
    DVec3::new(
        (f64::from(rgbe[0]) + 0.5) * f,
        (f64::from(rgbe[1]) + 0.5) * f,
        (f64::from(rgbe[2]) + 0.5) * f,
    )
}

/// Triangles of the element mesh as vertex index triples, counter-clockwise
/// seen from the front: its conforming triangulation, as the software
/// renderer draws it ([`Mesh::triangles`]).
#[must_use]
pub fn triangles(mesh: &Mesh) -> Vec<[u32; 3]> {
    mesh.triangles().into_iter().map(|t| t.corners).collect()
}

/// The mesh message: magic, vertex count `V`, triangle count `T`, then
/// `V` positions (3 f32, metres), `V` reflectances (3 f32: the ambient term
/// is added as `rho ambient`), `T` triangles (3 u32), all little-endian.
#[must_use]
pub fn mesh_message(scene: &Scene, mesh: &Mesh) -> Vec<u8> {
    let triangles = triangles(mesh);
    let v = mesh.vertices.len();
    let mut out = Vec::with_capacity(12 + 24 * v + 12 * triangles.len());
    out.extend_from_slice(&MESH_MAGIC);
    out.extend_from_slice(&(v as u32).to_le_bytes());
    out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for vertex in &mesh.vertices {
        put_vec3(&mut out, vertex.position);
    }
    for vertex in &mesh.vertices {
        put_vec3(&mut out, scene.surfaces[vertex.surface as usize].rho);
    }
    for t in &triangles {
        for i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    out
}

fn put_vec3(out: &mut Vec<u8>, v: DVec3) {
    for x in v.as_vec3().to_array() {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// A colour frame bringing a client from `previous` (what it was last
/// sent, `None` for nothing yet) to `current`: magic, the snapshot's
/// sequence number (u32), the number `n` of vertices carried (u32), flags
/// (u32, [`FLAG_FULL`]), the ambient term (3 f32, W/m^2), then, unless the
/// frame is full, `n` ascending vertex indices (u32), then `n` RGBE
/// colours (4 bytes each). A frame is full when the client has nothing
/// yet or when more than half the vertices changed (indices would then
/// cost more than they save).
#[must_use]
pub fn colour_frame(
    seq: u64,
    ambient: DVec3,
    current: &[Rgbe],
    previous: Option<&[Rgbe]>,
) -> Vec<u8> {
    let changed: Option<Vec<u32>> = previous
        .filter(|p| p.len() == current.len())
        .map(|p| {
            (0..current.len() as u32)
                .filter(|&i| p[i as usize] != current[i as usize])
                .collect()
        })
        .filter(|c: &Vec<u32>| 2 * c.len() <= current.len());
    let n = changed.as_ref().map_or(current.len(), Vec::len);
    let mut out = Vec::with_capacity(COLOURS_HEADER + 8 * n);
    out.extend_from_slice(&COLOURS_MAGIC);
    // The sequence number wraps after 2^32 snapshots, more than a century
    // at four a second.
    out.extend_from_slice(&(seq as u32).to_le_bytes());
    out.extend_from_slice(&(n as u32).to_le_bytes());
    let flags = if changed.is_none() { FLAG_FULL } else { 0 };
    out.extend_from_slice(&flags.to_le_bytes());
    put_vec3(&mut out, ambient);
    match changed {
        None => {
            for c in current {
                out.extend_from_slice(c);
            }
        }
        Some(indices) => {
            for i in &indices {
                out.extend_from_slice(&i.to_le_bytes());
            }
            for &i in &indices {
                out.extend_from_slice(&current[i as usize]);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use radiosity::mesh::MeshSettings;

    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    /// Applies a frame to a client's colours, read straight from the
    /// documented layout.
    fn apply(frame: &[u8], colours: &mut [Rgbe]) {
        assert_eq!(frame[..4], COLOURS_MAGIC);
        let n = u32_at(frame, 8) as usize;
        let full = u32_at(frame, 12) & FLAG_FULL != 0;
        if full {
            assert_eq!(n, colours.len());
            assert_eq!(frame.len(), COLOURS_HEADER + 4 * n);
            for (i, c) in colours.iter_mut().enumerate() {
                let at = COLOURS_HEADER + 4 * i;
                c.copy_from_slice(&frame[at..at + 4]);
            }
        } else {
            assert_eq!(frame.len(), COLOURS_HEADER + 8 * n);
            for k in 0..n {
                let i = u32_at(frame, COLOURS_HEADER + 4 * k) as usize;
                let at = COLOURS_HEADER + 4 * n + 4 * k;
                colours[i].copy_from_slice(&frame[at..at + 4]);
            }
        }
    }

    #[test]
    fn rgbe_known_values() {
        // 1.0 = 0.5 2^1: mantissa byte 128, exponent byte 129 (Radiance).
        assert_eq!(rgbe(DVec3::ONE), [128, 128, 128, 129]);
        assert_eq!(rgbe(DVec3::new(1.0, 0.5, 0.0)), [128, 64, 0, 129]);
        assert_eq!(rgbe(DVec3::ZERO), [0; 4]);
        assert_eq!(rgbe(DVec3::new(-1.0, f64::NAN, 0.0)), [0; 4]);
        assert_eq!(rgbe(DVec3::splat(1e-40)), [0; 4]);
        assert_eq!(rgbe_to_rgb([0, 0, 0, 0]), DVec3::ZERO);
        let huge = rgbe(DVec3::splat(f64::INFINITY));
        assert_eq!(huge, [255, 255, 255, 255]);
    }

    proptest! {
        /// The largest channel comes back within 1/128 relative, the
        /// others within 1/128 of the largest.
        #[test]
        fn rgbe_round_trip(r in 0.0..1e6f64, g in 0.0..1e6f64, b in 0.0..1e6f64, e in -100i32..100) {
            let c = DVec3::new(r, g, b) * 2f64.powi(e);
            prop_assume!(c.max_element() >= 1e-30);
            let back = rgbe_to_rgb(rgbe(c));
            let tolerance = c.max_element() / 128.0;
            for k in 0..3 {
                prop_assert!((back[k] - c[k]).abs() <= tolerance, "{c} -> {back}");
            }
        }
    }

    #[test]
    fn frames_bring_a_client_up_to_date() {
        let a: Vec<Rgbe> = (0..10u8).map(|i| [i, i, i, 130]).collect();
        let mut client = vec![[0u8; 4]; 10];
        let full = colour_frame(7, DVec3::new(0.5, 0.25, 0.125), &a, None);
        assert_eq!(u32_at(&full, 4), 7);
        assert_eq!(u32_at(&full, 12), FLAG_FULL);
        let ambient: Vec<f32> = (0..3)
            .map(|k| f32::from_le_bytes(full[16 + 4 * k..20 + 4 * k].try_into().unwrap()))
            .collect();
        assert_eq!(ambient, [0.5, 0.25, 0.125]);
        apply(&full, &mut client);
        assert_eq!(client, a);

        let mut b = a.clone();
        b[3] = [9, 9, 9, 131];
        b[8] = [1, 2, 3, 120];
        let delta = colour_frame(8, DVec3::ZERO, &b, Some(&a));
        assert_eq!(u32_at(&delta, 8), 2);
        assert_eq!(u32_at(&delta, 12), 0);
        assert_eq!((u32_at(&delta, 28), u32_at(&delta, 32)), (3, 8));
        apply(&delta, &mut client);
        assert_eq!(client, b);

        // Nothing changed: an empty frame still carries the ambient term.
        let none = colour_frame(9, DVec3::ONE, &b, Some(&b));
        assert_eq!(none.len(), COLOURS_HEADER);

        // Most changed: a full frame is smaller.
        let c: Vec<Rgbe> = b.iter().map(|x| [x[0], x[1], x[2], 140]).collect();
        let most = colour_frame(10, DVec3::ZERO, &c, Some(&b));
        assert_eq!(u32_at(&most, 12), FLAG_FULL);
        apply(&most, &mut client);
        assert_eq!(client, c);
    }

    /// The mesh message holds the mesh's positions and reflectances, and
    /// its triangles turn counter-clockwise around the surface normal (a
    /// browser culls the back faces by winding, as the renderer culls by
    /// plane).
    #[test]
    fn mesh_message_layout_and_winding() {
        let scene = radiosity::scene::load("cornell").unwrap();
        let sized = MeshSettings::default().sized_for(&scene);
        let settings = MeshSettings {
            element_size: 4.0 * sized.element_size,
            ..sized
        };
        let mesh = Mesh::build(&scene, &settings).unwrap();
        let m = mesh_message(&scene, &mesh);
        let v = u32_at(&m, 4) as usize;
        let t = u32_at(&m, 8) as usize;
        assert_eq!(v, mesh.vertices.len());
        assert_eq!(t, mesh.triangles().len());
        assert_eq!(m.len(), 12 + 24 * v + 12 * t);
        let f = |at: usize| f64::from(f32::from_le_bytes(m[at..at + 4].try_into().unwrap()));
        let position = |i: usize| DVec3::new(f(12 + 12 * i), f(16 + 12 * i), f(20 + 12 * i));
        for (i, vertex) in mesh.vertices.iter().enumerate() {
            assert!((position(i) - vertex.position).length() < 1e-5);
            let rho = scene.surfaces[vertex.surface as usize].rho;
            let at = 12 + 12 * v + 12 * i;
            assert!((DVec3::new(f(at), f(at + 4), f(at + 8)) - rho).length() < 1e-6);
        }
        for k in 0..t {
            let at = 12 + 24 * v + 12 * k;
            let [a, b, c] = [0, 4, 8].map(|o| u32_at(&m, at + o) as usize);
            let normal = mesh.vertices[a].normal;
            let turn = (position(b) - position(a)).cross(position(c) - position(a));
            assert!(turn.dot(normal) > 0.0, "triangle {k} is clockwise");
        }
    }
}
