//! The inputs the commands share: camera files, rig logs, ground truths, and the dispatch on
//! a file's descriptor type.

use std::path::{Path, PathBuf};

use ibc_camera_models::Rig;
use ibc_pipeline::data::io::{DescriptorLayout, read_descriptor_layout, read_log, read_truth};
use ibc_pipeline::data::{GroundTruth, RigLog};
use ibc_vocab_tree::Descriptor;

use super::CliError;
use super::progress::Bars;

/// Reads the camera file: a CamOdoCal folder (or its `extrinsic.txt`), else a Kalibr camchain.
pub(super) fn read_cameras(path: &Path) -> Result<Rig, CliError> {
    let error = |source| CliError::Cameras {
        path: path.to_owned(),
        source: Box::new(source),
    };
    if path.is_dir() {
        Rig::read_camodocal_dir(path).map_err(error)
    } else if path.file_name().is_some_and(|n| n == "extrinsic.txt") {
        Rig::read_camodocal_dir(path.parent().unwrap_or(Path::new("."))).map_err(error)
    } else {
        Rig::read_kalibr(path).map_err(error)
    }
}

/// The descriptor layout of the rig log at `path` (read from its header only).
pub(super) fn log_layout(path: &Path) -> Result<DescriptorLayout, CliError> {
    read_descriptor_layout(path).map_err(|source| CliError::Data {
        what: "rig log",
        source,
    })
}

/// Reads the ground truth given with `--truth`, if any.
pub(super) fn read_truth_arg(path: Option<&PathBuf>) -> Result<Option<GroundTruth>, CliError> {
    path.map(|p| {
        read_truth(p).map_err(|source| CliError::Data {
            what: "ground truth",
            source,
        })
    })
    .transpose()
}

/// Reads the rig log (a progress step), and checks that `truth` (from `truth_path`) is its
/// truth.
pub(super) fn read_log_checked<D: Descriptor>(
    path: &Path,
    truth: Option<(&GroundTruth, &PathBuf)>,
    bars: &Bars,
) -> Result<RigLog<D>, CliError> {
    bars.step("reading the log");
    let log = read_log::<D>(path).map_err(|source| CliError::Data {
        what: "rig log",
        source,
    });
    bars.done();
    let log = log?;
    if let Some((truth, truth_path)) = truth {
        truth
            .check_log(&log.camera_names, log.frames.len())
            .map_err(|source| CliError::TruthMismatch {
                path: truth_path.clone(),
                source,
            })?;
    }
    Ok(log)
}

/// Whether `path` is an SQLite file (a COLMAP database) rather than an ibc file: its first 16
/// bytes are SQLite's magic. False when it cannot be read (the ibc reader then says why).
pub(super) fn is_sqlite(path: &Path) -> bool {
    use std::io::Read;
    const MAGIC: &[u8; 16] = b"SQLite format 3\0";
    let mut head = Vec::with_capacity(16);
    ibc_camera_models::io::open_regular(path)
        .ok()
        .and_then(|(f, _)| f.take(16).read_to_end(&mut head).ok())
        .is_some_and(|_| head == MAGIC)
}

/// Calls `$run::<D>($args...)` with `D` the descriptor type of `$layout` among the types
/// COLMAP's database holds (binary 256 and 512 bits, SIFT as 128 floats), or returns
/// [`CliError::UnsupportedDescriptor`].
macro_rules! with_colmap_descriptor {
    ($layout:expr, $run:ident($($arg:expr),*)) => {{
        use ibc_vocab_tree::DescriptorKind;
        let layout = $layout;
        match (layout.kind, layout.width) {
            (DescriptorKind::Binary, 4) => $run::<[u64; 4]>($($arg),*),
            (DescriptorKind::Binary, 8) => $run::<[u64; 8]>($($arg),*),
            (DescriptorKind::Float, 128) => $run::<[f32; 128]>($($arg),*),
            _ => Err(CliError::UnsupportedDescriptor(layout)),
        }
    }};
}
pub(super) use with_colmap_descriptor;

/// Calls `$run::<D>($args...)` with `D` the descriptor type of `$layout`
/// ([`ibc_pipeline::data::io::DescriptorLayout`]), or returns
/// [`CliError::UnsupportedDescriptor`].
macro_rules! with_descriptor {
    ($layout:expr, $run:ident($($arg:expr),*)) => {{
        use ibc_vocab_tree::DescriptorKind;
        let layout = $layout;
        match (layout.kind, layout.width) {
            (DescriptorKind::Binary, 4) => $run::<[u64; 4]>($($arg),*),
            (DescriptorKind::Binary, 8) => $run::<[u64; 8]>($($arg),*),
            (DescriptorKind::Float, 32) => $run::<[f32; 32]>($($arg),*),
            (DescriptorKind::Float, 64) => $run::<[f32; 64]>($($arg),*),
            (DescriptorKind::Float, 128) => $run::<[f32; 128]>($($arg),*),
            _ => Err(CliError::UnsupportedDescriptor(layout)),
        }
    }};
}
pub(super) use with_descriptor;
