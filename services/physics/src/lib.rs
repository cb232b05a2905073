//! glint-physics: pure models shared by the simulator and the estimators.
//!
//! No I/O, no clock, no randomness in the models (`rng` is the seeded generator that tests and
//! offline synthesis draw from); f64 SI units throughout (angles in radians unless a name says
//! otherwise). Every module states its math and cites docs/math.md or
//! docs/materials.md.
//!
//! - [`frames`]: elementary rotations, cross-product matrix, RSW ↔ LVLH_N (§0, §6.3)
//! - [`orbit`]: circular orbits and the LVLH-nadir DCM (§1.1)
//! - [`sun`]: low-precision Sun direction (§6.2)
//! - [`cw`]: Clohessy–Wiltshire dynamics and STMs (§3.8, §7.1)
//! - [`camera`]: seed-002 pinhole camera, CAM_X convention (§3.1–3.5)
//! - [`fisheye`]: seed-003 equidistant fisheye and the Earth's angular radius (§4.1)
//! - [`brdf`]: multi-lobe Beckmann BRDF (§1.3)
//! - [`two_facet`]: seed-000 two-facet model, design rows, attitude matrices (§1.2–1.6)
//! - [`materials`]: spectral BRDF parameters and solar irradiance (materials.md §3)
//! - [`satellite`]: facet model of the seed-000 satellite and its spectral flux (§1.2, §1.7)
//! - [`hover`]: the seed-000 GEO hover geometry (§1.7)
//! - [`rigid_body`]: Euler's equations and the tanh inertia parametrisation (§5.4)
//! - [`stereo`]: rectified stereo projection and triangulation (§5.5)
//! - [`photometry`]: Ashikhmin–Shirley facets from OBJ text, shadowing, magnitudes (§2.1–2.4)

pub mod brdf;
pub mod camera;
pub mod cw;
pub mod fisheye;
pub mod frames;
pub mod hover;
pub mod materials;
pub mod orbit;
pub mod photometry;
pub mod rigid_body;
pub mod rng;
pub mod satellite;
pub mod stereo;
pub mod sun;
pub mod two_facet;
