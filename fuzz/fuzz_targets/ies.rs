#![no_main]
//! Fuzz target: an IES LM-63 photometric file read and evaluated in every direction
//! (`lightloom_nodes::ies`).

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(photometry) = lightloom_nodes::ies::Photometry::parse(data) {
        for k in 0..64 {
            let value = photometry.candela(f64::from(k) * 3.0, f64::from(k) * 11.0);
            assert!(value.is_finite() && value >= 0.0, "candela {value}");
        }
    }
});
