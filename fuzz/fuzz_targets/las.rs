#![no_main]
//! The LAS/LAZ reader on arbitrary bytes (byte 104 of the header says which).

#[path = "common.rs"]
mod common;

use asbuilt_plan::io::Format;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let laz = data.get(104).is_some_and(|b| b & 0xC0 != 0);
    common::read(data, if laz { Format::Laz } else { Format::Las }, None)
});
