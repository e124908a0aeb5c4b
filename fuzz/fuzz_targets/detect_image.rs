//! Fuzz target: `twincell_fuzz::detect_image` on arbitrary bytes.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| twincell_fuzz::detect_image(data));
