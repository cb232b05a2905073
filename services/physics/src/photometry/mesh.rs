//! Facet models from Wavefront OBJ text (docs/math.md §2.1): every face a facet, as the user
//! drew it (no subdivision). `v x y z` vertices in metres; `f a b c …` faces of three or more
//! vertices, `a`, `a/t`, `a//n` or `a/t/n` (only the vertex index is read; negative indices
//! count back from the last vertex); every other statement (`o`, `g`, `vt`, `vn`, `s`,
//! `usemtl`, `mtllib`, comments) is ignored. Faces are counter-clockwise seen from outside: the
//! outward normal follows the right-hand rule, the in-plane u axis lies along the face's first
//! edge and `v = n × u`.
//!
//! Written here rather than read with an OBJ crate: a facet must stay the polygon the user
//! drew (no triangulation or vertex merging), and a bad line must be named by its line and
//! column.

use nalgebra::Vector3;

use super::ashikhmin_shirley::Material;

/// One planar facet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Facet {
    pub area_m2: f64,
    /// Centroid [m] in the body frame.
    pub centre_m: Vector3<f64>,
    /// Outward normal and the in-plane axes (`u × v = n`).
    pub n: Vector3<f64>,
    pub u: Vector3<f64>,
    pub v: Vector3<f64>,
    pub material: Material,
}

/// A faceted body: its facets, and the triangles of every facet (a fan from its first vertex)
/// for the ray casts. A fan covers a concave facet with triangles of both orientations: a
/// point is on the facet when the signs of the triangles holding it do not cancel.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    pub facets: Vec<Facet>,
    pub triangles: Vec<FanTriangle>,
    /// The diagonal of the vertices' bounding box [m] (sets the ray casts' offsets).
    pub size_m: f64,
}

impl Shape {
    /// Total facet area [m²].
    pub fn area_m2(&self) -> f64 {
        self.facets.iter().map(|f| f.area_m2).sum()
    }

    /// Σ A n over the facets: zero for a closed surface.
    pub fn area_vector(&self) -> Vector3<f64> {
        self.facets.iter().map(|f| f.n * f.area_m2).sum()
    }

    /// The enclosed volume by the divergence theorem, ⅓ Σ A (c·n) [m³]: positive when the
    /// normals point outward (closed surfaces only).
    pub fn volume_m3(&self) -> f64 {
        self.facets
            .iter()
            .map(|f| f.area_m2 * f.centre_m.dot(&f.n))
            .sum::<f64>()
            / 3.0
    }

    /// The same shape scaled by `k` in length (areas by k²).
    pub fn scaled(&self, k: f64) -> Shape {
        Shape {
            facets: (self.facets.iter())
                .map(|f| Facet {
                    area_m2: f.area_m2 * k * k,
                    centre_m: f.centre_m * k,
                    ..*f
                })
                .collect(),
            triangles: (self.triangles.iter())
                .map(|t| FanTriangle {
                    vertices_m: t.vertices_m.map(|p| p * k),
                    ..*t
                })
                .collect(),
            size_m: self.size_m * k,
        }
    }
}

/// One triangle of a facet's fan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FanTriangle {
    pub facet: usize,
    pub vertices_m: [Vector3<f64>; 3],
    /// +1 where it turns with the facet's normal, −1 against it.
    pub sign: i32,
}

/// A problem in OBJ text: 1-based line and column, and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("line {line}, column {column}: {message}")]
pub struct ObjError {
    pub line: usize,
    pub column: usize,
    pub message: String,
}

/// A face whose vertices deviate from its plane by more than this fraction of its size is
/// refused (a facet must be planar).
const PLANARITY: f64 = 1e-6;

/// Reads OBJ text into a shape whose every facet has `material`.
pub fn parse_obj(text: &str, material: Material) -> Result<Shape, ObjError> {
    let mut vertices: Vec<Vector3<f64>> = vec![];
    let mut faces: Vec<(usize, Vec<usize>)> = vec![];
    for (l, raw) in text.lines().enumerate() {
        let line = l + 1;
        let content = raw.split('#').next().unwrap_or_default();
        let mut words = words_with_columns(content);
        let Some((_, keyword)) = words.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let mut xyz = [0.0; 3];
                for (k, slot) in xyz.iter_mut().enumerate() {
                    let (column, w) = words.next().ok_or_else(|| ObjError {
                        line,
                        column: raw.len() + 1,
                        message: format!("a vertex needs x, y and z; coordinate {} missing", k + 1),
                    })?;
                    *slot = w
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| ObjError {
                            line,
                            column,
                            message: format!("`{w}` is not a finite number"),
                        })?;
                }
                vertices.push(Vector3::from(xyz));
            }
            "f" => {
                let mut idx = vec![];
                for (column, w) in words {
                    let first = w.split('/').next().unwrap_or_default();
                    let bad = |m: String| ObjError {
                        line,
                        column,
                        message: m,
                    };
                    let i: i64 = first
                        .parse()
                        .map_err(|_| bad(format!("`{w}` is not a vertex index")))?;
                    let n = vertices.len() as i64;
                    let resolved = match i {
                        1.. if i <= n => i - 1,
                        ..=-1 if i.unsigned_abs() <= n as u64 => n + i,
                        _ => {
                            return Err(bad(format!(
                                "vertex index {i} out of range: {n} vertices defined so far \
                                 (1..={n}, or -1..=-{n} from the last)"
                            )))
                        }
                    };
                    idx.push(resolved as usize);
                }
                if idx.len() < 3 {
                    return Err(ObjError {
                        line,
                        column: 1,
                        message: format!(
                            "a face needs 3 or more vertices, this one has {}",
                            idx.len()
                        ),
                    });
                }
                faces.push((line, idx));
            }
            _ => {}
        }
    }
    if faces.is_empty() {
        return Err(ObjError {
            line: text.lines().count().max(1),
            column: 1,
            message: "no faces (`f` lines)".into(),
        });
    }
    let mut facets = vec![];
    let mut triangles = vec![];
    for (line, idx) in faces {
        let p: Vec<Vector3<f64>> = idx.iter().map(|&i| vertices[i]).collect();
        let facet = facet_of(&p, material).map_err(|message| ObjError {
            line,
            column: 1,
            message,
        })?;
        for k in 1..p.len() - 1 {
            let turn = (p[k] - p[0]).cross(&(p[k + 1] - p[0])).dot(&facet.n);
            if turn != 0.0 {
                triangles.push(FanTriangle {
                    facet: facets.len(),
                    vertices_m: [p[0], p[k], p[k + 1]],
                    sign: if turn > 0.0 { 1 } else { -1 },
                });
            }
        }
        facets.push(facet);
    }
    // The bounding box's diagonal: the size that sets the ray casts' offsets.
    let (lo, hi) = vertices.iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), v| (lo.inf(v), hi.sup(v)),
    );
    let size_m = (hi - lo).norm();
    Ok(Shape {
        facets,
        triangles,
        size_m,
    })
}

/// Whitespace-separated words with their 1-based columns.
fn words_with_columns(s: &str) -> impl Iterator<Item = (usize, &str)> {
    s.split_whitespace().map(move |w| {
        let offset = w.as_ptr() as usize - s.as_ptr() as usize;
        (offset + 1, w)
    })
}

/// A planar polygon's facet: Newell's normal and area, the area-weighted centroid of its fan.
fn facet_of(p: &[Vector3<f64>], material: Material) -> Result<Facet, String> {
    let mut newell = Vector3::zeros();
    for (i, a) in p.iter().enumerate() {
        newell += a.cross(&p[(i + 1) % p.len()]);
    }
    let area = 0.5 * newell.norm();
    let size = p.iter().map(|a| (a - p[0]).norm()).fold(0.0, f64::max);
    let has_area = area > 1e-12 * size * size; // false for NaN too
    if !has_area || size == 0.0 {
        return Err("a degenerate face (no area: repeated or collinear vertices)".into());
    }
    let n = newell / (2.0 * area);
    if let Some(k) = p
        .iter()
        .position(|a| (a - p[0]).dot(&n).abs() > PLANARITY * size)
    {
        return Err(format!(
            "a face that is not planar: its vertex {} lies {:.3e} m off the plane of the others",
            k + 1,
            (p[k] - p[0]).dot(&n).abs()
        ));
    }
    let mut centre = Vector3::zeros();
    let mut weight = 0.0;
    for k in 1..p.len() - 1 {
        let a = 0.5 * (p[k] - p[0]).cross(&(p[k + 1] - p[0])).dot(&n);
        centre += (p[0] + p[k] + p[k + 1]) / 3.0 * a;
        weight += a;
    }
    let first_edge = p[1] - p[0];
    let u = (first_edge - n * n.dot(&first_edge))
        .try_normalize(0.0)
        .ok_or("a face whose first edge has no length")?;
    Ok(Facet {
        area_m2: area,
        centre_m: centre / weight,
        n,
        u,
        v: n.cross(&u),
        material,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) const MATERIAL: Material = Material {
        r_diff: 0.3,
        r_spec: 0.5,
        n_u: 100.0,
        n_v: 100.0,
    };

    /// A unit cube from 0 to 1, faces counter-clockwise from outside, in the forms other tools
    /// write (quads, `v/vt/vn`, `v//vn`, negative indices, objects and groups).
    pub(crate) const CUBE: &str = "\
# a cube exported by a modelling tool
mtllib cube.mtl
o Cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vt 0 0
vn 0 0 -1
g bottom_and_top
usemtl grey
s off
f 1/1/1 4/1/1 3/1/1 2/1/1
f 5//1 6//1 7//1 8//1
g sides
f 1 2 6 5
f 2 3 7 6
f -5 -1 -2 -6
f 4 1 5 8
";

    #[test]
    fn an_obj_cube_has_six_outward_unit_facets() {
        let s = parse_obj(CUBE, MATERIAL).unwrap();
        assert_eq!(s.facets.len(), 6);
        assert_eq!(s.triangles.len(), 12);
        for f in &s.facets {
            assert!((f.area_m2 - 1.0).abs() < 1e-15);
            // outward: the normal points away from the cube's centre
            assert!((f.centre_m - Vector3::repeat(0.5)).dot(&f.n) > 0.49);
            assert!((f.u.cross(&f.v) - f.n).norm() < 1e-15);
        }
        let bottom = &s.facets[0];
        assert_eq!(bottom.n, Vector3::new(0.0, 0.0, -1.0));
        assert_eq!(bottom.centre_m, Vector3::new(0.5, 0.5, 0.0));
        // u along the first edge, vertex 1 → 4
        assert_eq!(bottom.u, Vector3::new(0.0, 1.0, 0.0));
        assert!(s.area_vector().norm() < 1e-15);
        assert!((s.volume_m3() - 1.0).abs() < 1e-15);
        assert!((s.size_m - 3f64.sqrt()).abs() < 1e-15);
        let big = s.scaled(2.0);
        assert!((big.area_m2() - 24.0).abs() < 1e-12 && (big.volume_m3() - 8.0).abs() < 1e-12);
    }

    #[test]
    fn a_concave_polygon_facet_keeps_its_area_and_centroid() {
        // An L-shaped hexagon in z = 0 of area 3 (a 2 × 2 square less its 1 × 1 corner).
        let text = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 1 2 3 4 5 6\n";
        let s = parse_obj(text, MATERIAL).unwrap();
        let f = &s.facets[0];
        assert!((f.area_m2 - 3.0).abs() < 1e-14);
        // centroid of the L: (3·1 − 1·1.5) / 2 per axis... by parts: squares at (0.5,0.5),
        // (1.5,0.5), (0.5,1.5) → (2.5/3, 2.5/3)
        assert!((f.centre_m - Vector3::new(2.5 / 3.0, 2.5 / 3.0, 0.0)).norm() < 1e-14);
        assert_eq!(f.n, Vector3::z());
    }

    #[test]
    fn bad_obj_lines_are_named_by_line_and_column() {
        let e = parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", MATERIAL).unwrap_err();
        assert_eq!((e.line, e.column), (4, 7));
        assert!(
            e.message.contains("out of range") && e.message.contains("1..=3"),
            "{e}"
        );
        let e = parse_obj("v 0 zero 0\n", MATERIAL).unwrap_err();
        assert_eq!((e.line, e.column), (1, 5));
        let e = parse_obj("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", MATERIAL).unwrap_err();
        assert!(e.message.contains("degenerate"), "{e}");
        let e = parse_obj(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0.5\nf 1 2 3 4\n",
            MATERIAL,
        )
        .unwrap_err();
        assert!(e.message.contains("not planar"), "{e}");
        let e = parse_obj(
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9223372036854775808\n",
            MATERIAL,
        )
        .unwrap_err();
        assert!(e.message.contains("out of range"), "{e}");
        let e = parse_obj("v 0 0 0\nv 1 0 0\nf 1 2\n", MATERIAL).unwrap_err();
        assert!(e.message.contains("3 or more"), "{e}");
        assert!(parse_obj("# nothing\n", MATERIAL)
            .unwrap_err()
            .message
            .contains("no faces"));
    }
}
