//! Compact GPU encodings of the products and detail terms (what the renderer uploads and
//! `shaders/mesh_wavelet.wgsl` decodes).

/// Packs a non-negative RGB value into the shared-exponent `RGB9E5` format (9-bit mantissas,
/// one 5-bit exponent; `EXT_texture_shared_exponent`): 4 bytes instead of 12, relative error
/// under 2⁻⁹ of the largest channel. `shaders/mesh_wavelet.wgsl` decodes it.
pub fn rgb9e5(rgb: [f32; 3]) -> u32 {
    const MANTISSA_BITS: i32 = 9;
    const BIAS: i32 = 15;
    const MAX: f32 = (511.0 / 512.0) * 65536.0; // (2^9 - 1)/2^9 · 2^(31 - 15)
    let c = rgb.map(|v| if v.is_finite() { v.clamp(0.0, MAX) } else { 0.0 });
    let max = c[0].max(c[1]).max(c[2]);
    if max <= 0.0 {
        return 0;
    }
    // ⌊log2 max⌋ is the float's own exponent (a subnormal's reads -127, which the clamp lifts).
    let floor_log2 = ((max.to_bits() >> 23) & 0xff) as i32 - 127;
    let mut exponent = floor_log2.max(-BIAS - 1) + 1 + BIAS;
    // 2^k for k in -24..=8, built from its bits.
    let mut scale = f32::from_bits(((exponent - BIAS - MANTISSA_BITS + 127) as u32) << 23);
    if (max / scale + 0.5).floor() as u32 == 512 {
        exponent += 1;
        scale *= 2.0;
    }
    let m = c.map(|v| ((v / scale + 0.5).floor() as u32).min(511));
    m[0] | (m[1] << 9) | (m[2] << 18) | ((exponent.clamp(0, 31) as u32) << 27)
}

/// [`rgb9e5`] of every RGB triple of an interleaved slice (on every core).
pub fn rgb9e5_all(interleaved: &[f32]) -> Vec<u32> {
    use rayon::prelude::*;
    const CHUNK: usize = 4096;
    let mut packed = vec![0u32; interleaved.len() / 3];
    packed.par_chunks_mut(CHUNK).zip(interleaved.par_chunks(3 * CHUNK)).for_each(|(packed, rgb)| {
        for (packed, c) in packed.iter_mut().zip(rgb.chunks_exact(3)) {
            *packed = rgb9e5([c[0], c[1], c[2]]);
        }
    });
    packed
}

/// Inverse of [`rgb9e5`] (the shader's decode, for tests).
pub fn rgb9e5_decode(v: u32) -> [f32; 3] {
    let scale = 2f32.powi((v >> 27) as i32 - 15 - 9);
    [(v & 0x1ff) as f32 * scale, ((v >> 9) & 0x1ff) as f32 * scale, ((v >> 18) & 0x1ff) as f32 * scale]
}

/// Kept detail terms as `wavelet_relight.wgsl` writes them: five words per slot, the node in
/// the low half of the first and the nine details as half floats after it (clamped to
/// half's range).
pub fn detail_words(nodes: &[u32], values: &[[f32; 9]]) -> Vec<u32> {
    let half = |x: f32| u32::from(half::f16::from_f32(x.clamp(-65504.0, 65504.0)).to_bits());
    nodes
        .iter()
        .zip(values)
        .flat_map(|(node, d)| {
            [
                node | half(d[0]) << 16,
                half(d[1]) | half(d[2]) << 16,
                half(d[3]) | half(d[4]) << 16,
                half(d[5]) | half(d[6]) << 16,
                half(d[7]) | half(d[8]) << 16,
            ]
        })
        .collect()
}

/// The inverse of [`detail_words`] for one slot: its node and details.
pub fn detail_decode(words: &[u32]) -> (u32, [f32; 9]) {
    let half = |bits: u32| half::f16::from_bits(bits as u16).to_f32();
    let all = [
        words[0] >> 16,
        words[1] & 0xffff,
        words[1] >> 16,
        words[2] & 0xffff,
        words[2] >> 16,
        words[3] & 0xffff,
        words[3] >> 16,
        words[4] & 0xffff,
        words[4] >> 16,
    ];
    (words[0] & 0xffff, all.map(half))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb9e5_round_trips_within_its_precision() {
        let values = [[0.0, 0.0, 0.0], [1.0, 0.5, 0.25], [1e-4, 3e-3, 2e-2], [123.4, 0.01, 56.0], [0.3, 0.3, 0.3]];
        for v in values {
            let d = rgb9e5_decode(rgb9e5(v));
            let max = v[0].max(v[1]).max(v[2]);
            for c in 0..3 {
                assert!((d[c] - v[c]).abs() <= max / 512.0 + 1e-12, "{v:?} -> {d:?}");
            }
        }
        assert_eq!(rgb9e5([f32::NAN, -1.0, 0.0]), 0);
        assert!(rgb9e5_decode(rgb9e5([1e9, 0.0, 0.0]))[0] > 6.0e4);
    }

    /// The shared exponent read from the float's bits is the one `⌊log2⌋` in f64 gives, so
    /// the packing equals the format's definition (mantissas rounded in f32), over 24 decades, at powers of two and
    /// their neighbours, and in subnormals; `rgb9e5_all` packs each triple alike.
    #[test]
    fn rgb9e5_equals_the_formats_definition() {
        use rand::Rng;
        // The exponent from f64's log2; the mantissas rounded in f32, as the shader does.
        let definition = |rgb: [f32; 3]| -> u32 {
            let max_value = (511.0 / 512.0) * 65536.0;
            let c = rgb.map(|v| if v.is_finite() { v.clamp(0.0, max_value) } else { 0.0 });
            let max = c[0].max(c[1]).max(c[2]);
            if max <= 0.0 {
                return 0;
            }
            let mut exponent = (f64::from(max).log2().floor() as i32).max(-16) + 16;
            let mut scale = 2f64.powi(exponent - 24) as f32;
            if (max / scale + 0.5).floor() as u32 == 512 {
                exponent += 1;
                scale *= 2.0;
            }
            let m = c.map(|v| ((v / scale + 0.5).floor() as u32).min(511));
            m[0] | (m[1] << 9) | (m[2] << 18) | ((exponent.clamp(0, 31) as u32) << 27)
        };
        use rand::SeedableRng;
        let mut rng = rand::rngs::SmallRng::seed_from_u64(3);
        let mut values: Vec<[f32; 3]> = (0..100_000)
            .map(|_| std::array::from_fn(|_| 10f32.powf(rng.random_range(-12.0..7.0)) * rng.random_range(0.0..1.0)))
            .collect();
        for k in -30..17 {
            let p = 2f32.powi(k);
            for v in [p, f32::from_bits(p.to_bits() - 1), f32::from_bits(p.to_bits() + 1), p * (1.0 - 1.0 / 1024.0)] {
                values.push([v, v * 0.3, 0.0]);
            }
        }
        values.push([1e-40, 0.0, 5e-39]);
        for v in &values {
            assert_eq!(rgb9e5(*v), definition(*v), "{v:?}");
        }
        let interleaved: Vec<f32> = values.iter().flatten().copied().collect();
        let packed = rgb9e5_all(&interleaved);
        assert!(packed.iter().zip(&values).all(|(p, v)| *p == rgb9e5(*v)));
    }
}
