//! Self-shadowing and occlusion (docs/math.md §2.3): a facet facing both the Sun and the
//! observer counts only if the rays from its centre (offset by ε along its normal) towards the
//! Sun and towards the observer leave the body without hitting another facet (Möller–Trumbore
//! against each facet's fan). Binary at the facet centre: a partly shadowed facet is lit or
//! dark as its centre is.

use nalgebra::Vector3;

use super::mesh::Shape;

/// Offset of a ray's origin along the facet normal, and the smallest accepted hit distance,
/// as fractions of the shape's size.
const EPSILON: f64 = 1e-6;

/// Möller–Trumbore: the distance `t` along unit-or-not direction `d` from `o` at which the ray
/// meets triangle `tri`, if it does (`t` may be negative: behind the origin).
pub fn moller_trumbore(o: &Vector3<f64>, d: &Vector3<f64>, tri: &[Vector3<f64>; 3]) -> Option<f64> {
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let p = d.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-12 * e1.norm() * e2.norm() * d.norm() {
        return None; // parallel to the triangle's plane
    }
    let inv = 1.0 / det;
    let tv = o - tri[0];
    let u = tv.dot(&p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = tv.cross(&e1);
    let v = d.dot(&q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(&q) * inv)
}

/// Whether the ray from `o` along `d` meets a facet other than `from` in front of it. A facet's
/// fan triangles are consecutive in `shape.triangles`: their signed hits are summed facet by
/// facet.
fn blocked(shape: &Shape, from: usize, o: &Vector3<f64>, d: &Vector3<f64>) -> bool {
    let min_t = EPSILON * shape.size_m;
    let (mut facet, mut winding, mut crosses) = (usize::MAX, 0, false);
    for t in &shape.triangles {
        if t.facet != facet {
            if winding != 0 {
                return true;
            }
            (facet, winding) = (t.facet, 0);
            // The ray can meet this facet only where it crosses its plane ahead of the origin.
            let f = &shape.facets[facet];
            let along = d.dot(&f.n);
            crosses = facet != from && along != 0.0 && (f.centre_m - o).dot(&f.n) / along > min_t;
        }
        if crosses && moller_trumbore(o, d, &t.vertices_m).is_some_and(|t_hit| t_hit > min_t) {
            winding += t.sign;
        }
    }
    winding != 0
}

/// Whether facet `i` faces the Sun and the observer (unit directions in the body frame) and
/// neither is hidden from its centre by another facet.
pub fn facet_visible(shape: &Shape, i: usize, sun: &Vector3<f64>, obs: &Vector3<f64>) -> bool {
    let f = &shape.facets[i];
    if !(f.n.dot(sun) > 0.0 && f.n.dot(obs) > 0.0) {
        return false;
    }
    let o = f.centre_m + f.n * (EPSILON * shape.size_m);
    !blocked(shape, i, &o, sun) && !blocked(shape, i, &o, obs)
}

/// [`facet_visible`] of every facet.
pub fn visible_facets(shape: &Shape, sun: &Vector3<f64>, obs: &Vector3<f64>) -> Vec<bool> {
    (0..shape.facets.len())
        .map(|i| facet_visible(shape, i, sun, obs))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photometry::mesh::parse_obj;
    use crate::photometry::mesh::tests::{CUBE, MATERIAL};

    #[test]
    fn moller_trumbore_by_hand() {
        let tri = [Vector3::zeros(), Vector3::x(), Vector3::y()];
        let down = -Vector3::z();
        // from (0.25, 0.25, 2) straight down: hits at t = 2
        let t = moller_trumbore(&Vector3::new(0.25, 0.25, 2.0), &down, &tri).unwrap();
        assert!((t - 2.0).abs() < 1e-15);
        // a longer direction vector scales t: t = 1 for d = (0, 0, −2)
        let t = moller_trumbore(&Vector3::new(0.25, 0.25, 2.0), &(down * 2.0), &tri).unwrap();
        assert!((t - 1.0).abs() < 1e-15);
        // beside the triangle (u + v > 1), and parallel to it
        assert!(moller_trumbore(&Vector3::new(0.6, 0.6, 2.0), &down, &tri).is_none());
        assert!(moller_trumbore(&Vector3::new(0.2, 0.2, 2.0), &Vector3::x(), &tri).is_none());
        // behind the origin: negative t
        let t = moller_trumbore(&Vector3::new(0.25, 0.25, -1.0), &down, &tri).unwrap();
        assert!((t + 1.0).abs() < 1e-15);
    }

    /// The unit cube with a 3 × 3 m panel (a closed slab 0.1 m thick) floating 1 m above its
    /// top: with the Sun overhead the panel shades the cube's top; with the Sun low the top is
    /// lit, and seen from overhead the panel hides it.
    fn cube_under_a_panel() -> Shape {
        let mut text = CUBE.to_string();
        text.push_str(
            "o panel\n\
             v -1 -1 2\nv 2 -1 2\nv 2 2 2\nv -1 2 2\n\
             v -1 -1 2.1\nv 2 -1 2.1\nv 2 2 2.1\nv -1 2 2.1\n\
             f 9 12 11 10\nf 13 14 15 16\nf 9 10 14 13\nf 10 11 15 14\nf 11 12 16 15\nf 12 9 13 16\n",
        );
        parse_obj(&text, MATERIAL).unwrap()
    }

    #[test]
    fn a_panel_shades_and_hides_the_face_below_it() {
        let s = cube_under_a_panel();
        let top = 1; // the cube's second face, z = 1
        assert_eq!(s.facets[top].n, Vector3::z());
        let low = Vector3::new(1.0, 0.0, 0.2).normalize();
        let overhead = Vector3::z();
        let side = Vector3::new(0.0, 1.0, 0.2).normalize();
        // Sun overhead, observer low: the top is in the panel's shadow
        assert!(!visible_facets(&s, &overhead, &low)[top]);
        // Sun low, observer low on another side: lit and seen
        assert!(visible_facets(&s, &low, &side)[top]);
        // Sun low, observer overhead: lit but hidden by the panel
        assert!(!visible_facets(&s, &low, &overhead)[top]);
        // the panel's upper face sees everything overhead; the cube's bottom faces away
        let vis = visible_facets(&s, &overhead, &overhead);
        assert!(vis[7] && !vis[0]);
    }

    #[test]
    fn a_convex_body_shades_nothing_that_faces_the_light() {
        let s = parse_obj(CUBE, MATERIAL).unwrap();
        let sun = Vector3::new(0.3, 0.5, 0.81).normalize();
        let obs = Vector3::new(-0.2, 0.6, 0.77).normalize();
        let vis = visible_facets(&s, &sun, &obs);
        for (f, v) in s.facets.iter().zip(vis) {
            assert_eq!(v, f.n.dot(&sun) > 0.0 && f.n.dot(&obs) > 0.0);
        }
    }

    #[test]
    fn a_concave_facet_blocks_only_where_it_is() {
        // An L-shaped plate at z = 1 over a small square at z = 0 (facing up): light from
        // overhead passes through the L's missing corner (x, y in 1..2) and not elsewhere.
        let text = "v 0 0 1\nv 2 0 1\nv 2 1 1\nv 1 1 1\nv 1 2 1\nv 0 2 1\n\
                    f 6 5 4 3 2 1\n\
                    v 1.4 1.4 0\nv 1.6 1.4 0\nv 1.6 1.6 0\nv 1.4 1.6 0\nf 7 8 9 10\n\
                    v 0.4 0.4 0\nv 0.6 0.4 0\nv 0.6 0.6 0\nv 0.4 0.6 0\nf 11 12 13 14\n";
        let s = parse_obj(text, MATERIAL).unwrap();
        let up = Vector3::z();
        let vis = visible_facets(&s, &up, &up);
        assert!(vis[1], "under the missing corner: lit");
        assert!(!vis[2], "under the L: shaded");
    }
}
