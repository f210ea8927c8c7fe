//! Shared helpers of the `cli_*` integration tests: running the `ibc` binary.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::{Command, Output};

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
