//! The keypoint and descriptor sections shared by maps and logs: encoding, and decoding image
//! by image in parallel (the sections are sliced per image first, so every image is
//! independent; errors are reported for the first bad image in file order).

use nalgebra::Vector2;

use super::bytes::put_f64;
use super::error::{FormatError, invalid};
use crate::data::ImageFeatures;
use ibc_vocab_tree::Descriptor;

/// Little-endian `f64` from exactly eight bytes.
#[inline(always)]
fn le_f64(b: &[u8]) -> f64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(b);
    f64::from_le_bytes(a)
}

/// Appends the keypoint section (`x`, `y` as `f64`, 16 bytes per feature) and then the
/// descriptor section ([`Descriptor::BYTES`] per feature) of `images`, in order.
pub(crate) fn put_feature_sections<'a, D: Descriptor + 'a>(
    out: &mut Vec<u8>,
    images: impl Iterator<Item = &'a ImageFeatures<D>> + Clone,
) {
    for image in images.clone() {
        for k in &image.keypoints {
            put_f64(out, k.x);
            put_f64(out, k.y);
        }
    }
    for image in images {
        image.descriptors.iter().for_each(|d| d.write_le(out));
    }
}

/// The index of each image's first feature.
pub(crate) fn starts(counts: &[usize]) -> Vec<usize> {
    let mut out = Vec::with_capacity(counts.len());
    let mut s = 0;
    for c in counts {
        out.push(s);
        s += c;
    }
    out
}

/// Decodes one image's features from its keypoint bytes (16 per feature) and descriptor bytes
/// ([`Descriptor::BYTES`] per feature), whose lengths the caller sliced to match.
/// `what` names the image in errors (`"map image 3"`).
pub(crate) fn decode_features<D: Descriptor>(
    keypoints: &[u8],
    descriptors: &[u8],
    what: &dyn Fn() -> String,
) -> Result<ImageFeatures<D>, FormatError> {
    let n = keypoints.len() / 16;
    let mut features = ImageFeatures {
        keypoints: Vec::with_capacity(n),
        descriptors: Vec::with_capacity(n),
    };
    for (k, c) in keypoints.chunks_exact(16).enumerate() {
        let p = Vector2::new(le_f64(&c[..8]), le_f64(&c[8..]));
        if !(p.x.is_finite() && p.y.is_finite()) {
            return Err(invalid(format!("{} keypoint {k} is not finite", what())));
        }
        features.keypoints.push(p);
    }
    for (k, c) in descriptors
        .chunks_exact(D::BYTES.max(1))
        .take(n)
        .enumerate()
    {
        let d = D::read_le(c);
        if !d.is_finite() {
            return Err(invalid(format!(
                "{} descriptor {k} has a non-finite value",
                what()
            )));
        }
        features.descriptors.push(d);
    }
    Ok(features)
}
