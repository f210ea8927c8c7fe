//! Bounded inputs: camera files are read only from regular files of bounded size, and YAML
//! aliases and deep nesting are refused before a document is built.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::time::{Duration, Instant};

use ibc_camera_models::camodocal::{parse_camera, read_camera};
use ibc_camera_models::io::IoError;
use ibc_camera_models::{CameraFileError, MAX_FILE_BYTES, MAX_YAML_DEPTH, Rig};

/// "Billion laughs": nine levels of nine, 306 bytes that a loader which copies aliased nodes
/// expands to 9^9 = 387 million scalars (the file reported, of the same shape, had 335 bytes
/// and grew to 8 GB in 60 s).
fn alias_bomb() -> String {
    let mut s = String::from("a: &a [x,x,x,x,x,x,x,x,x]\n");
    let names = ['a', 'b', 'c', 'd', 'e', 'f', 'g', 'h', 'i'];
    for w in names.windows(2) {
        let refs = vec![format!("*{}", w[0]); 9].join(",");
        s.push_str(&format!("{}: &{} [{refs}]\n", w[1], w[1]));
    }
    s
}

/// Run `f` on another thread and fail if it takes more than `limit` (a reader that blocks
/// must fail the test, not hang it).
fn within<T: Send + 'static>(limit: Duration, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || tx.send(f()));
    rx.recv_timeout(limit).expect("the reader blocked")
}

fn is_not_regular(e: &CameraFileError, path: &Path) -> bool {
    matches!(e, CameraFileError::Io(IoError::NotRegularFile { path: p }) if p == path)
}

#[test]
fn a_yaml_alias_bomb_is_refused_at_once() {
    let bomb = alias_bomb();
    assert_eq!(bomb.len(), 306);
    let start = Instant::now();
    let e = parse_camera(&bomb).unwrap_err();
    assert!(matches!(e, CameraFileError::YamlAlias { line: 2 }), "{e}");
    assert!(e.to_string().contains("aliases"), "{e}");
    let e = Rig::from_kalibr_str(&bomb).unwrap_err();
    assert!(matches!(e, CameraFileError::YamlAlias { line: 2 }), "{e}");
    // From a file, with the file named, and after the dropped `%YAML:1.0` line.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bomb.yaml");
    std::fs::write(&path, format!("%YAML:1.0\n---\n{bomb}")).unwrap();
    match read_camera(&path).unwrap_err() {
        CameraFileError::InFile { path: p, source } => {
            assert_eq!(p, path);
            assert!(
                matches!(*source, CameraFileError::YamlAlias { line: 4 }),
                "{source}"
            );
        }
        other => panic!("{other}"),
    }
    // Microseconds in practice; a loader that expanded it took minutes and gigabytes.
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "{:?}",
        start.elapsed()
    );
}

#[test]
fn anchors_without_aliases_are_accepted() {
    let text = "%YAML:1.0\n---\nmodel_type: PINHOLE\ncamera_name: &n cam\nimage_width: 752\n\
                image_height: 480\ndistortion_parameters: &d\n   k1: -0.28\n   k2: 0.07\n   \
                p1: 0.0002\n   p2: 0.00002\nprojection_parameters:\n   fx: 458.6\n   fy: 457.3\n   \
                cx: 367.2\n   cy: 248.4\n";
    assert_eq!(parse_camera(text).unwrap().name, "cam");
}

#[test]
fn deep_nesting_is_refused_before_the_document_is_built() {
    // 300 000 nested block sequences in 600 kB: built and dropped, it overflows the stack.
    let deep = format!("{}x\n", "- ".repeat(300_000));
    assert!(deep.len() as u64 <= MAX_FILE_BYTES);
    let e = Rig::from_kalibr_str(&deep).unwrap_err();
    assert!(
        matches!(e, CameraFileError::YamlTooDeep { line: 1, limit } if limit == MAX_YAML_DEPTH),
        "{e}"
    );
    let flow = format!("cam0: {}{}", "[".repeat(100), "]".repeat(100));
    assert!(matches!(
        Rig::from_kalibr_str(&flow),
        Err(CameraFileError::YamlTooDeep { .. })
    ));
    // The deepest real file (a camchain's T_cn_cnm1 rows) is 4 levels.
    let ok = format!("{}x\n", "- ".repeat(MAX_YAML_DEPTH));
    assert!(!matches!(
        Rig::from_kalibr_str(&ok),
        Err(CameraFileError::YamlTooDeep { .. })
    ));
}

#[test]
fn syntax_errors_count_the_dropped_directive_lines() {
    let e = parse_camera("%YAML:1.0\n---\nmodel_type: [unclosed\n").unwrap_err();
    match e {
        CameraFileError::Yaml { message } => assert!(message.contains("line 4"), "{message}"),
        other => panic!("{other}"),
    }
}

#[test]
fn a_directory_is_not_a_camera_file() {
    let dir = tempfile::tempdir().unwrap();
    let e = read_camera(dir.path()).unwrap_err();
    assert!(is_not_regular(&e, dir.path()), "{e}");
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let e = Rig::read_kalibr(dir.path()).unwrap_err();
    assert!(is_not_regular(&e, dir.path()), "{e}");
}

#[cfg(unix)]
#[test]
fn dev_zero_is_refused_without_reading_it() {
    let zero = Path::new("/dev/zero");
    let e = within(Duration::from_secs(10), move || read_camera(zero)).unwrap_err();
    assert!(is_not_regular(&e, zero), "{e}");
    let e = within(Duration::from_secs(10), move || Rig::read_kalibr(zero)).unwrap_err();
    assert!(is_not_regular(&e, zero), "{e}");
}

#[cfg(unix)]
#[test]
fn a_fifo_is_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("camchain.yaml");
    let status = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo");
    assert!(status.success());
    let path = fifo.clone();
    let e = within(Duration::from_secs(10), move || Rig::read_kalibr(&path)).unwrap_err();
    assert!(is_not_regular(&e, &fifo), "{e}");
    // As a rig folder's extrinsic.txt too.
    std::fs::remove_file(&fifo).unwrap();
    let extrinsic = dir.path().join("extrinsic.txt");
    let status = std::process::Command::new("mkfifo")
        .arg(&extrinsic)
        .status()
        .expect("mkfifo");
    assert!(status.success());
    let d = dir.path().to_owned();
    let e = within(Duration::from_secs(10), move || Rig::read_camodocal_dir(&d)).unwrap_err();
    assert!(is_not_regular(&e, &extrinsic), "{e}");
}

#[test]
fn an_oversized_file_is_refused_naming_its_size() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.yaml");
    let over = usize::try_from(MAX_FILE_BYTES).unwrap() + 1;
    std::fs::write(&path, "#".repeat(over)).unwrap();
    let e = Rig::read_kalibr(&path).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::Io(IoError::TooLarge { path: p, size, limit })
            if p == &path && *size == MAX_FILE_BYTES + 1 && *limit == MAX_FILE_BYTES),
        "{e}"
    );
    assert!(e.to_string().contains("1048577"), "{e}");
    // Exactly the limit is read (and is then an empty document, in the named file).
    std::fs::write(&path, "#".repeat(over - 1)).unwrap();
    match Rig::read_kalibr(&path).unwrap_err() {
        CameraFileError::InFile { source, .. } => {
            assert!(matches!(*source, CameraFileError::Empty))
        }
        other => panic!("{other}"),
    }
}

#[test]
fn text_that_is_not_utf8_is_an_io_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("latin1.yaml");
    std::fs::write(&path, b"camera_name: caf\xe9\n").unwrap();
    let e = read_camera(&path).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::Io(IoError::NotText { path: p }) if p == &path),
        "{e}"
    );
}
