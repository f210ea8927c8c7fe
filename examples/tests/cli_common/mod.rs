//! Shared helpers of the `cli_*` integration tests: running the `ibc` binary.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ibc_pipeline::sim::{Scenario, SimulatedWorld};

/// Runs `ibc` with `args`.
pub fn ibc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ibc"))
        .args(args)
        .output()
        .unwrap()
}

/// Standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Writes a scenario file: the `base` scenario at `scale`.
pub fn scenario_file(dir: &Path, base: &str, scale: f64) -> String {
    let path = dir.join(format!("{base}-{scale}.yaml"));
    std::fs::write(&path, format!("version: 1\nbase: {base}\nscale: {scale}\n")).unwrap();
    path.to_str().unwrap().to_owned()
}

/// The entries of a folder (empty when it does not exist).
pub fn entries(dir: &Path) -> Vec<String> {
    match std::fs::read_dir(dir) {
        Ok(rd) => rd
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect(),
        Err(_) => Vec::new(),
    }
}

/// True when two JSON values are equal, numbers to within 1e-9 (relative) or 1e-12.
pub fn json_close(a: &serde_json::Value, b: &serde_json::Value, at: &str) -> Result<(), String> {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            if (x - y).abs() <= 1e-12 + 1e-9 * x.abs().max(y.abs()) {
                Ok(())
            } else {
                Err(format!("{at}: {x} != {y}"))
            }
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .try_for_each(|(i, (x, y))| json_close(x, y, &format!("{at}[{i}]"))),
        (Value::Object(x), Value::Object(y)) if x.len() == y.len() => {
            x.iter().try_for_each(|(k, v)| {
                let w = y.get(k).ok_or_else(|| format!("{at}.{k} missing"))?;
                json_close(v, w, &format!("{at}.{k}"))
            })
        }
        _ if a == b => Ok(()),
        _ => Err(format!("{at}: {a} != {b}")),
    }
}

/// A small simulated world written to `dir` (map, log, camchain, truth).
pub fn world(dir: &Path) -> ibc_pipeline::sim::WrittenFiles {
    let scenario = Scenario::builtin("garage").unwrap().with_scale(0.05);
    SimulatedWorld::simulate(&scenario)
        .unwrap()
        .write(dir)
        .unwrap()
}

/// Checks a failed run: exit code 1, nothing on stdout, one line on stderr starting with
/// `error: ` and containing every one of `expected`.
pub fn check_failure(o: &Output, expected: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert_eq!(err.lines().count(), 1, "not one line: {err}");
    assert!(err.starts_with("error: "), "{err}");
    for e in expected {
        assert!(err.contains(e), "`{e}` not in: {err}");
    }
}

/// A small simulated world in a temporary folder.
pub struct Files {
    /// Keeps the folder alive.
    pub _dir: tempfile::TempDir,
    /// The map.
    pub map: PathBuf,
    /// The rig log.
    pub log: PathBuf,
    /// The Kalibr camchain.
    pub cameras: PathBuf,
    /// The ground truth.
    pub truth: PathBuf,
    /// The folder.
    pub dir: PathBuf,
}

/// The garage at scale 0.05 written to a temporary folder.
pub fn files() -> Files {
    let dir = tempfile::tempdir().unwrap();
    let w = world(dir.path());
    Files {
        dir: dir.path().to_owned(),
        _dir: dir,
        map: w.map,
        log: w.log,
        cameras: w.cameras,
        truth: w.truth,
    }
}
