//! The byte-level parts shared by the map and rig-log formats: the common header, a cursor
//! that reads little-endian values (its callers check lengths first), pose records and the
//! checksum trailer.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use super::FORMAT_VERSION;
use super::checksum::xxh64;
use ibc_vocab_tree::{Descriptor, DescriptorKind};

use super::descriptor::descriptor_layout;
use super::error::{DescriptorLayout, FormatError, invalid};

/// Bytes of the common header (magic to file length).
pub(crate) const COMMON_HEADER_LEN: usize = 32;
/// Bytes of the checksum trailer.
pub(crate) const CHECKSUM_LEN: usize = 8;
/// Bytes of a pose record: `tx, ty, tz, qw, qx, qy, qz` as `f64`.
pub(crate) const POSE_LEN: usize = 56;
/// How far a stored quaternion's norm may be from 1 (it is normalized on reading).
pub(crate) const UNIT_TOLERANCE: f64 = 1e-6;

/// The two kinds of files, with their magics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FileKind {
    /// `IBCMAP\0\0`.
    Map,
    /// `IBCLOG\0\0`.
    Log,
}

impl FileKind {
    pub(crate) fn magic(self) -> [u8; 8] {
        match self {
            Self::Map => *b"IBCMAP\0\0",
            Self::Log => *b"IBCLOG\0\0",
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            Self::Map => "map",
            Self::Log => "rig log",
        }
    }
}

/// Starts a file: the common header with a placeholder length, patched by [`finish`].
pub(crate) fn start<D: Descriptor>(kind: FileKind, capacity: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(capacity);
    out.extend_from_slice(&kind.magic());
    put_u32(&mut out, FORMAT_VERSION);
    out.push(D::KIND.code());
    out.extend_from_slice(&[0; 3]);
    put_u32(&mut out, descriptor_layout::<D>().width);
    put_u32(&mut out, 0);
    put_u64(&mut out, 0);
    out
}

/// Ends a file: writes its length into the header and appends the checksum.
pub(crate) fn finish(mut out: Vec<u8>) -> Vec<u8> {
    let len = (out.len() + CHECKSUM_LEN) as u64;
    out[24..32].copy_from_slice(&len.to_le_bytes());
    let sum = xxh64(&out);
    put_u64(&mut out, sum);
    out
}

/// Checks everything about a file that does not depend on its kind's counts: length,
/// magic, version, descriptor layout, declared length, checksum. `minimum` is the length of
/// an empty file of the kind.
pub(crate) fn check_envelope<D: Descriptor>(
    bytes: &[u8],
    kind: FileKind,
    minimum: usize,
) -> Result<(), FormatError> {
    let actual = bytes.len() as u64;
    let magic_ok = |k: FileKind| bytes.len() >= 8 && bytes[..8] == k.magic();
    let other = match kind {
        FileKind::Map => FileKind::Log,
        FileKind::Log => FileKind::Map,
    };
    if !magic_ok(kind) {
        if magic_ok(other) {
            return Err(FormatError::WrongFileKind {
                expected: kind.name(),
                found: other.name(),
            });
        }
        if bytes.len() < minimum && kind.magic().starts_with(&bytes[..bytes.len().min(8)]) {
            return Err(FormatError::TooShort {
                len: actual,
                minimum: minimum as u64,
                expected: kind.name(),
            });
        }
        return Err(FormatError::BadMagic {
            expected: kind.name(),
            found: bytes[..bytes.len().min(8)].escape_ascii().to_string(),
        });
    }
    if bytes.len() < minimum {
        return Err(FormatError::TooShort {
            len: actual,
            minimum: minimum as u64,
            expected: kind.name(),
        });
    }
    let header = read_common_header(bytes)?;
    let found = header.layout;
    if found != descriptor_layout::<D>() {
        return Err(FormatError::DescriptorMismatch {
            found,
            expected: descriptor_layout::<D>(),
        });
    }
    if header.declared != actual {
        return Err(FormatError::LengthMismatch {
            declared: header.declared,
            actual,
        });
    }
    let body = &bytes[..bytes.len() - CHECKSUM_LEN];
    let stored = Cursor::new(&bytes[bytes.len() - CHECKSUM_LEN..]).u64();
    let computed = xxh64(body);
    if stored != computed {
        return Err(FormatError::ChecksumMismatch { stored, computed });
    }
    if !header.reserved_zero {
        return Err(invalid(
            "reserved header bytes 13..16 and 20..24 must be zero",
        ));
    }
    Ok(())
}

/// The fields of the common header after the magic.
struct CommonHeader {
    layout: DescriptorLayout,
    declared: u64,
    reserved_zero: bool,
}

/// Reads the common header of `bytes` (at least [`COMMON_HEADER_LEN`] long): version,
/// descriptor layout, declared length.
fn read_common_header(bytes: &[u8]) -> Result<CommonHeader, FormatError> {
    let mut r = Cursor::new(&bytes[8..COMMON_HEADER_LEN]);
    let version = r.u32();
    if version != FORMAT_VERSION {
        return Err(FormatError::UnsupportedVersion {
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    let code = r.u8();
    let reserved = r.bytes(3).iter().all(|b| *b == 0);
    let width = r.u32();
    let reserved2 = r.u32() == 0;
    let declared = r.u64();
    let kind =
        DescriptorKind::from_code(code).ok_or(FormatError::UnknownDescriptorKind { code })?;
    Ok(CommonHeader {
        layout: DescriptorLayout { kind, width },
        declared,
        reserved_zero: reserved && reserved2,
    })
}

/// The length of a file to write as a buffer capacity, or an error when it overflows.
pub(crate) fn buffer_len(len: Option<u64>, what: &str) -> Result<usize, FormatError> {
    len.and_then(|l| usize::try_from(l).ok())
        .ok_or_else(|| invalid(format!("the {what} is too large for this platform")))
}

/// Checked arithmetic for layout lengths: `None` on overflow.
pub(crate) fn layout_len(terms: &[(u64, u64)]) -> Option<u64> {
    terms.iter().try_fold(0u64, |acc, &(count, size)| {
        count.checked_mul(size).and_then(|t| acc.checked_add(t))
    })
}

/// A little-endian reader over a slice whose length the caller has already checked against
/// everything it reads: reading past the end yields zeros rather than panicking, and the
/// layout checks make that unreachable.
pub(crate) struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0 }
    }

    /// The next `n` bytes (fewer at the end of the slice).
    pub(crate) fn bytes(&mut self, n: usize) -> &'a [u8] {
        let start = self.at.min(self.bytes.len());
        let end = self.at.saturating_add(n).min(self.bytes.len());
        self.at = self.at.saturating_add(n);
        &self.bytes[start..end]
    }

    fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut a = [0u8; N];
        let b = self.bytes(N);
        a[..b.len()].copy_from_slice(b);
        a
    }

    pub(crate) fn u8(&mut self) -> u8 {
        self.array::<1>()[0]
    }

    pub(crate) fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.array())
    }

    pub(crate) fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.array())
    }

    pub(crate) fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.array())
    }

    /// A pose record, validated: finite, and a unit quaternion within [`UNIT_TOLERANCE`]
    /// (normalized). `what` names the record in errors.
    pub(crate) fn pose(
        &mut self,
        what: &dyn Fn() -> String,
    ) -> Result<Isometry3<f64>, FormatError> {
        let v: [f64; 7] = std::array::from_fn(|_| self.f64());
        pose_from_array(v).map_err(|why| invalid(format!("{}: {why}", what())))
    }
}

/// A pose from `[tx, ty, tz, qw, qx, qy, qz]`, or why not.
pub(crate) fn pose_from_array(v: [f64; 7]) -> Result<Isometry3<f64>, String> {
    if !v.iter().all(|x| x.is_finite()) {
        return Err("the pose has a non-finite value".to_owned());
    }
    let q = Quaternion::new(v[3], v[4], v[5], v[6]);
    let norm = q.norm();
    if (norm - 1.0).abs() > UNIT_TOLERANCE {
        return Err(format!(
            "the quaternion [w, x, y, z] has norm {norm}, not 1 (within {UNIT_TOLERANCE})"
        ));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        unit_quaternion(q),
    ))
}

/// A unit quaternion from one whose norm is within [`UNIT_TOLERANCE`] of 1: kept bit for bit
/// when its norm is 1 to rounding (so writing and reading give back the same pose), otherwise
/// normalized.
pub(crate) fn unit_quaternion(q: Quaternion<f64>) -> UnitQuaternion<f64> {
    if (q.norm() - 1.0).abs() <= 4.0 * f64::EPSILON {
        UnitQuaternion::new_unchecked(q)
    } else {
        UnitQuaternion::from_quaternion(q)
    }
}

/// `[tx, ty, tz, qw, qx, qy, qz]` of a pose.
pub(crate) fn pose_to_array(p: &Isometry3<f64>) -> [f64; 7] {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    [t.x, t.y, t.z, q.w, q.i, q.j, q.k]
}

/// Checks a pose before writing it: finite (a unit quaternion by construction).
pub(crate) fn check_pose(p: &Isometry3<f64>, what: &dyn Fn() -> String) -> Result<(), FormatError> {
    if pose_to_array(p).iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(invalid(format!(
            "{}: the pose has a non-finite value",
            what()
        )))
    }
}

pub(crate) fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

pub(crate) fn put_u64(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(&v.to_le_bytes());
}

pub(crate) fn put_f64(out: &mut Vec<u8>, v: f64) {
    out.extend_from_slice(&v.to_le_bytes());
}

/// A pose record; `None` writes 56 zero bytes.
pub(crate) fn put_pose(out: &mut Vec<u8>, p: Option<&Isometry3<f64>>) {
    match p {
        Some(p) => pose_to_array(p).iter().for_each(|v| put_f64(out, *v)),
        None => out.extend_from_slice(&[0; POSE_LEN]),
    }
}

/// A count that the format stores as `u32`.
pub(crate) fn count_u32(n: usize, what: &str) -> Result<u32, FormatError> {
    u32::try_from(n).map_err(|_| invalid(format!("{n} {what} do not fit the format's u32 count")))
}

/// The descriptor layout in the common header of a map or a log (either kind).
pub(crate) fn peek_layout(header: &[u8]) -> Result<DescriptorLayout, FormatError> {
    let is = |k: FileKind| header.len() >= 8 && header[..8] == k.magic();
    let kind = if is(FileKind::Map) {
        FileKind::Map
    } else if is(FileKind::Log) {
        FileKind::Log
    } else {
        return Err(FormatError::BadMagic {
            expected: "map or rig log",
            found: header[..header.len().min(8)].escape_ascii().to_string(),
        });
    };
    if header.len() < COMMON_HEADER_LEN {
        return Err(FormatError::TooShort {
            len: header.len() as u64,
            minimum: COMMON_HEADER_LEN as u64,
            expected: kind.name(),
        });
    }
    Ok(read_common_header(header)?.layout)
}
