//! Reports of a calibration: the JSON report ([`Report`]), the text table like the paper's
//! Table I ([`text_table`]), SVG plots ([`top_view_svg`], [`error_histogram_svg`]) and the
//! output files (Kalibr camchain, CamOdoCal YAMLs and `extrinsic.txt`), written all or
//! nothing by [`write_outputs`]; the same for a self-calibration
//! ([`SelfCalibrationReport`], [`write_selfcalib_outputs`]).

mod files;
mod json;
pub(crate) mod plot;
mod selfcalib;
mod svg;
mod table;

pub use files::{OutputError, calibrated_rig, output_names, write_outputs};
pub use json::{
    CameraJson, CameraReprojectionJson, ChangeJson, HandEyeJson, InitializationJson, PatternJson,
    PoseJson, PoseStdJson, REPORT_FORMAT, REPORT_VERSION, RefinementJson, Report, ReprojectionJson,
    ResidualJson, WarningJson,
};
pub use selfcalib::{
    RoundJson, SELFCALIB_REPORT_FORMAT, SelfCalibCameraJson, SelfCalibWarning,
    SelfCalibrationReport, StdJson, self_calibrated_rig, self_calibration_top_view,
    write_selfcalib_outputs,
};
pub use svg::{error_histogram_svg, top_view_svg};
pub use table::text_table;
