//! Import of the DBoW2 text vocabulary format used by ORB-SLAM (`ORBvoc.txt`).
//!
//! The format, as ORB-SLAM's vocabulary files are laid out:
//!
//! - line 1: `k L scoring weighting` — branching, depth and DBoW2's scoring and weighting
//!   codes (see [`Scoring::code`], [`Weighting::code`]);
//! - then one line per node below the root, node ids counting from 1 in line order:
//!   `parent is_leaf d_1 … d_m weight`, where `parent` is the id of an earlier node (0 for the
//!   root), `is_leaf` is 0 or 1, the descriptor is `m` values (`8 W` bytes `0..=255` for a
//!   binary `[u64; W]`, packed as in [`binary_from_bytes`](crate::binary_from_bytes); `D`
//!   numbers for a float `[f32; D]`) and `weight` is the word's IDF weight (0 for internal
//!   nodes).
//!
//! Words are numbered in the order their leaves appear in the file, as DBoW2 numbers them, so
//! word ids agree with ORB-SLAM's. Nodes are renumbered breadth first (children in file
//! order) into the flat layout. Parsing allocates per array, never per node.

use std::io::{BufRead, Read};
use std::path::Path;

use crate::descriptor::Descriptor;
use crate::error::{Result, VocabError, VocabFileError};
use crate::scoring::Scoring;
use crate::vocabulary::{MAX_DEPTH, Vocabulary, VocabularyParts};
use crate::weighting::Weighting;

/// The longest line read, in bytes: a node line of `ORBvoc.txt` is about 100 bytes and a
/// 128-float descriptor in text about 2 kB, so 64 KiB refuses only what is not a vocabulary
/// (a binary file, `/dev/zero`) before it fills memory.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

fn text_error(line: usize, reason: impl Into<String>) -> VocabError {
    VocabFileError::Text {
        line,
        reason: reason.into(),
    }
    .into()
}

fn parse_header(line_no: usize, line: &str) -> Result<(u32, u32, Scoring, Weighting)> {
    let t: Vec<&str> = line.split_ascii_whitespace().collect();
    if t.len() != 4 {
        return Err(text_error(
            line_no,
            format!("the header must be `k L scoring weighting`, found `{line}`"),
        ));
    }
    let num = |s: &str, what: &str| {
        s.parse::<u32>().map_err(|_| {
            text_error(
                line_no,
                format!("{what} `{s}` is not a non-negative integer"),
            )
        })
    };
    let (k, l) = (num(t[0], "branching")?, num(t[1], "depth")?);
    let scoring = u8::try_from(num(t[2], "scoring")?)
        .ok()
        .and_then(Scoring::from_code)
        .ok_or_else(|| text_error(line_no, format!("unknown scoring code `{}`", t[2])))?;
    let weighting = u8::try_from(num(t[3], "weighting")?)
        .ok()
        .and_then(Weighting::from_code)
        .ok_or_else(|| text_error(line_no, format!("unknown weighting code `{}`", t[3])))?;
    if k < 1 || !(1..=MAX_DEPTH).contains(&l) {
        return Err(text_error(
            line_no,
            format!("branching {k} and depth {l}: need k >= 1 and 1 <= L <= {MAX_DEPTH}"),
        ));
    }
    Ok((k, l, scoring, weighting))
}

impl<D: Descriptor> Vocabulary<D> {
    /// Imports a DBoW2 / ORB-SLAM text vocabulary (see the [module docs](crate::dbow2_text)).
    /// `ORBvoc.txt` is read as `Vocabulary<[u64; 4]>`.
    pub fn from_dbow2_text(reader: impl BufRead) -> Result<Self> {
        let mut header = None;
        let mut parent: Vec<u32> = vec![0];
        let mut is_leaf: Vec<bool> = vec![false];
        let mut weight: Vec<f32> = vec![0.0];
        let mut centroid: Vec<D> = vec![D::zero()];
        let mut line_of: Vec<u32> = vec![1];
        let mut reader = reader;
        let mut bytes = Vec::new();
        let mut line_no = 0;
        loop {
            line_no += 1;
            bytes.clear();
            let read = Read::take(&mut reader, MAX_LINE_BYTES as u64 + 1)
                .read_until(b'\n', &mut bytes)
                .map_err(|e| text_error(line_no, format!("read error: {e}")))?;
            if read == 0 {
                break;
            }
            if bytes.len() > MAX_LINE_BYTES {
                return Err(text_error(
                    line_no,
                    format!(
                        "the line is longer than {MAX_LINE_BYTES} bytes: not a DBoW2 text vocabulary"
                    ),
                ));
            }
            let line = std::str::from_utf8(&bytes)
                .map_err(|_| text_error(line_no, "the line is not UTF-8 text"))?;
            if line.trim().is_empty() {
                continue;
            }
            if header.is_none() {
                header = Some(parse_header(line_no, line)?);
                continue;
            }
            let id = parent.len();
            let mut t = line.split_ascii_whitespace();
            let p: u32 = t
                .next()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| text_error(line_no, "the parent id is not an integer"))?;
            if p as usize >= id {
                return Err(text_error(
                    line_no,
                    format!("node {id} names parent {p}, which is not an earlier node"),
                ));
            }
            let leaf = match t.next() {
                Some("0") => false,
                Some("1") => true,
                other => {
                    return Err(text_error(
                        line_no,
                        format!("is_leaf must be 0 or 1, found {other:?}"),
                    ));
                }
            };
            let d = D::parse_dbow2(&mut t).map_err(|r| text_error(line_no, r))?;
            let w: f64 = t
                .next()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| text_error(line_no, "the node weight is missing or not a number"))?;
            if t.next().is_some() {
                return Err(text_error(line_no, "unexpected tokens after the weight"));
            }
            if !(w.is_finite() && w >= 0.0) {
                return Err(text_error(
                    line_no,
                    format!("weight {w} is not finite and >= 0"),
                ));
            }
            if id >= u32::MAX as usize - 1 {
                return Err(VocabError::TooManyNodes { nodes: id as u64 });
            }
            parent.push(p);
            is_leaf.push(leaf);
            weight.push(w as f32);
            centroid.push(d);
            line_of.push(u32::try_from(line_no).unwrap_or(u32::MAX));
        }
        let (branching, depth, scoring, weighting) =
            header.ok_or_else(|| text_error(1, "empty file: no header"))?;
        let n = parent.len();
        // Children of each node in file order (a stable counting sort by parent).
        let mut first = vec![0u32; n + 1];
        for &p in &parent[1..] {
            first[p as usize + 1] += 1;
        }
        for i in 0..n {
            first[i + 1] += first[i];
        }
        let mut fill = first.clone();
        let mut children = vec![0u32; n.saturating_sub(1)];
        for (id, &p) in parent.iter().enumerate().skip(1) {
            children[fill[p as usize] as usize] = id as u32;
            fill[p as usize] += 1;
        }
        for id in 0..n {
            let has_children = first[id] != first[id + 1];
            if id > 0 && has_children == is_leaf[id] {
                let reason = if is_leaf[id] {
                    format!("node {id} is marked as a leaf but has children")
                } else {
                    format!("node {id} is not marked as a leaf but has no children")
                };
                return Err(text_error(line_of[id] as usize, reason));
            }
        }
        // Breadth-first renumbering.
        let mut order: Vec<u32> = Vec::with_capacity(n);
        order.push(0);
        let mut new_id = vec![0u32; n];
        let mut child_start = Vec::with_capacity(n + 1);
        let mut i = 0;
        while i < order.len() {
            let old = order[i] as usize;
            new_id[old] = i as u32;
            child_start.push(order.len() as u32);
            order.extend_from_slice(&children[first[old] as usize..first[old + 1] as usize]);
            i += 1;
        }
        child_start.push(n as u32);
        let centroids = order.iter().map(|&o| centroid[o as usize]).collect();
        let leaves: Vec<usize> = (1..n).filter(|&id| is_leaf[id]).collect();
        let word_node = leaves.iter().map(|&id| new_id[id]).collect();
        let word_weights = leaves.iter().map(|&id| weight[id]).collect();
        Self::from_parts(VocabularyParts {
            branching,
            depth,
            weighting,
            scoring,
            child_start,
            centroids,
            word_node,
            word_weights,
        })
    }

    /// Imports a DBoW2 / ORB-SLAM text vocabulary file such as `ORBvoc.txt`.
    /// Only regular files are read (a FIFO would block, a device never end), and no line may
    /// exceed [`MAX_LINE_BYTES`].
    pub fn load_dbow2_text(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let (file, _) = ibc_camera_models::io::open_regular(path)?;
        Self::from_dbow2_text(std::io::BufReader::with_capacity(1 << 20, file))
            .map_err(|e| e.in_file(path))
    }
}
