//! Fuzz target: `twincell_fuzz::urdf` on arbitrary bytes.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| twincell_fuzz::urdf(data));
