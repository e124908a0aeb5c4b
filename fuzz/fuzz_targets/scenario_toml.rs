//! Fuzz target: `twincell_fuzz::scenario_toml` on arbitrary bytes.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| twincell_fuzz::scenario_toml(data));
