//! serde for the models (feature `serde`): image size and named parameters, validated on load.
//!
//! A model serializes as `{"width": .., "height": .., <parameter>: .., ...}` with the
//! parameter names of its `PARAM_NAMES`; deserializing runs the same validation as `new`, so a
//! file cannot produce a camera with, say, a negative focal length or stale derived limits.

use crate::{KannalaBrandt, PinholeRadtan, Unified};

/// Implements Serialize and Deserialize for a model through a plain struct of named fields.
macro_rules! serde_model {
    ($model:ident, $repr:ident, [$($field:ident),+]) => {
        #[derive(serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct $repr {
            width: u32,
            height: u32,
            $($field: f64,)+
        }

        impl serde::Serialize for $model {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                let [$($field),+] = self.params_array();
                $repr {
                    width: crate::CameraModel::width(self),
                    height: crate::CameraModel::height(self),
                    $($field,)+
                }
                .serialize(s)
            }
        }

        impl<'de> serde::Deserialize<'de> for $model {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let r = $repr::deserialize(d)?;
                $model::new(r.width, r.height, [$(r.$field),+]).map_err(serde::de::Error::custom)
            }
        }
    };
}

serde_model!(
    KannalaBrandt,
    KannalaBrandtRepr,
    [k1, k2, k3, k4, mu, mv, u0, v0]
);
serde_model!(
    PinholeRadtan,
    PinholeRadtanRepr,
    [k1, k2, p1, p2, fx, fy, cx, cy]
);
serde_model!(
    Unified,
    UnifiedRepr,
    [xi, k1, k2, p1, p2, gamma1, gamma2, u0, v0]
);
