#![doc = include_str!("../README.md")]

pub mod calib;
pub mod data;
pub mod intrinsics;
pub mod report;
pub mod sim;
