//! Fuzz target: `twincell_fuzz::batch_files` on arbitrary bytes.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| twincell_fuzz::batch_files(data));
