//! Serde for the physics crate's [`TwoFacetCoefficients`] (which has no serde derive):
//! `{ "panel": [11 numbers], "body": [11 numbers] }`.

use glint_physics::two_facet::{TwoFacetCoefficients, TERMS_PER_FACET};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Remote definition used with `#[serde(with = "serde_coeffs::Coeffs")]`.
#[derive(Serialize, Deserialize)]
#[serde(remote = "TwoFacetCoefficients")]
pub struct Coeffs {
    /// P_m.
    pub panel: [f64; TERMS_PER_FACET],
    /// B_m.
    pub body: [f64; TERMS_PER_FACET],
}

#[derive(Serialize, Deserialize)]
struct Wrapped(#[serde(with = "Coeffs")] TwoFacetCoefficients);

/// `Option<TwoFacetCoefficients>` (`null` when absent).
pub mod option {
    use super::*;

    /// Serialises `Some(c)` as the object and `None` as `null`.
    pub fn serialize<S: Serializer>(
        v: &Option<TwoFacetCoefficients>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        v.map(Wrapped).serialize(s)
    }

    /// Inverse of [`serialize`].
    pub fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<TwoFacetCoefficients>, D::Error> {
        Ok(Option::<Wrapped>::deserialize(d)?.map(|w| w.0))
    }
}
