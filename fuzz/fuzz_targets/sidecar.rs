#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| cvtrace_fuzz_targets::sidecar(data));
