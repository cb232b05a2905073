//! [001] Ground-based photometry of a faceted satellite (docs/math.md §2.1–2.4): the
//! Ashikhmin–Shirley BRDF of the light-curve literature, facet models read from Wavefront OBJ
//! text, self-shadowing and occlusion by ray casts at the facet centres, and the apparent
//! magnitude a ground station sees.
//!
//! Frames: every direction here is in the body frame B of the shape (the caller rotates the
//! Sun and observer directions into it once per sample); `sun` and `obs` are unit vectors from
//! the satellite to the Sun and to the observer.

pub mod ashikhmin_shirley;
pub mod flux;
pub mod mesh;
pub mod site;
pub mod visibility;

pub use ashikhmin_shirley::{rho_total, Material, SpecularDenominator};
pub use flux::{apparent_magnitude, flux_of_magnitude, normalised_flux, SUN_MAGNITUDE};
pub use mesh::{parse_obj, Facet, FanTriangle, ObjError, Shape};
pub use site::{geometry, geostationary, Geometry, Station, Unseen};
pub use visibility::{facet_visible, moller_trumbore, visible_facets};
