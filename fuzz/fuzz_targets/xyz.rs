#![no_main]
//! The XYZ/PTS text reader, and format detection, on arbitrary bytes. The first byte chooses
//! XYZ or PTS and the scan column, so one target covers both.

#[path = "common.rs"]
mod common;

use asbuilt_plan::io::{detect, Format};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&mode, text)) = data.split_first() else {
        return;
    };
    let _ = detect::detect(&text[..text.len().min(detect::SNIFF_LEN)]);
    let format = if mode & 1 == 0 { Format::Xyz } else { Format::Pts };
    let scan_column = (mode & 2 != 0).then_some(usize::from(mode >> 2) % 8);
    common::read(text, format, scan_column)
});
