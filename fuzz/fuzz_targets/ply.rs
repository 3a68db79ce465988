#![no_main]
//! The Ply reader on arbitrary bytes.

#[path = "common.rs"]
mod common;

use asbuilt_plan::io::Format;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| common::read(data, Format::Ply, None));
