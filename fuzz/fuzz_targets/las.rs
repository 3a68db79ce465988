#![no_main]
//! The LAS/LAZ reader on arbitrary bytes (byte 104 of the header says which).

#[path = "common.rs"]
mod common;

use asbuilt_plan::io::Format;
use libfuzzer_sys::fuzz_target;

/// The `laz` crate's decoders panic on some damaged compressed bytes, which no check of the
/// header can rule out; the reader catches those panics where it calls the decoder and names
/// the damage. They pass here. A panic anywhere else still reaches libFuzzer's hook, which
/// aborts: that is a finding.
fn let_decoder_panics_through() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let abort = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !info.location().is_some_and(|l| l.file().contains("/laz-")) {
                abort(info)
            }
        }));
    });
}

fuzz_target!(|data: &[u8]| {
    let_decoder_panics_through();
    let laz = data.get(104).is_some_and(|b| b & 0xC0 != 0);
    common::read(data, if laz { Format::Laz } else { Format::Las }, None)
});
