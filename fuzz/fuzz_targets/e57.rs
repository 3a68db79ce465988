#![no_main]
//! The E57 reader on arbitrary bytes. Every E57 page ends in a CRC-32C, so almost every mutation
//! would die at the first checksum; the target pads the input to whole pages, sets the header's
//! file length and rewrites every checksum, so the fuzzer reaches the XML and the binary
//! sections. (Bad checksums themselves are covered in `bad_files.rs`.)

#[path = "common.rs"]
mod common;

use asbuilt_plan::io::Format;
use libfuzzer_sys::fuzz_target;

const PAGE: usize = 1024;

fn crc32c(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0x82F6_3B78 } else { crc >> 1 };
        }
    }
    !crc
}

fuzz_target!(|data: &[u8]| {
    let mut b = data.to_vec();
    if b.len() >= 48 {
        b.resize(b.len().div_ceil(PAGE) * PAGE, 0);
        let len = b.len() as u64;
        b[16..24].copy_from_slice(&len.to_le_bytes());
        for page in b.chunks_exact_mut(PAGE) {
            let crc = crc32c(&page[..PAGE - 4]);
            page[PAGE - 4..].copy_from_slice(&crc.to_be_bytes());
        }
    }
    common::read(&b, Format::E57, None)
});
