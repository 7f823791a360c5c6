use super::*;

fn no_files(path: &str) -> Result<Image, String> {
    Err(format!("no file {path}"))
}

fn dab(at: [f64; 2], radius: f64, hardness: f64, colour: [f64; 3], blend: Blend) -> PaintOp {
    PaintOp::Stroke { points: vec![at], radius, hardness, colour, intensity: 1.0, blend }
}

/// A hard round dab covers the disc's area at every resolution (within a texel's border), and
/// the three blends follow their formulas on the texels it covers fully.
#[test]
fn strokes_cover_their_disc_and_blend() {
    for side in RESOLUTIONS {
        let op = dab([0.5, 0.5], 0.2, 1.0, [4.0, 0.0, 2.0], Blend::Mix);
        let t = render(&[op], side, &mut no_files).unwrap();
        let painted = t.radiance.iter().filter(|c| c[0] == 4.0).count() as f64 / (side * side) as f64;
        let disc = std::f64::consts::PI * 0.04;
        let border = 2.0 * std::f64::consts::PI * 0.2 / side as f64;
        assert!((painted - disc).abs() < border, "{side}: painted {painted} vs disc {disc}");
    }
    let base = PaintOp::Fill { colour: [2.0, 1.0, 0.5], intensity: 1.0 };
    let at = |t: &LightTexture| t.radiance[16 * 32 + 16];
    let mix = render(&[base.clone(), dab([0.5, 0.5], 0.1, 1.0, [1.0, 3.0, 0.0], Blend::Mix)], 32, &mut no_files);
    assert_eq!(at(&mix.unwrap()), [1.0, 3.0, 0.0]);
    let add = render(&[base.clone(), dab([0.5, 0.5], 0.1, 1.0, [1.0, 3.0, 0.0], Blend::Add)], 32, &mut no_files);
    assert_eq!(at(&add.unwrap()), [3.0, 4.0, 0.5]);
    let mul = render(&[base, dab([0.5, 0.5], 0.1, 1.0, [1.0, 3.0, 0.0], Blend::Multiply)], 32, &mut no_files);
    assert_eq!(at(&mul.unwrap()), [2.0, 3.0, 0.0]);
    // A soft brush falls off smoothly to nothing at its radius.
    assert_eq!(brush_coverage(0.05, 0.1, 0.5), 1.0);
    assert!((brush_coverage(0.075, 0.1, 0.5) - 0.5).abs() < 1e-12);
    assert_eq!(brush_coverage(0.1, 0.1, 0.5), 0.0);
}

/// Erasing and reshaping cut the emission, not the colour; a disc keeps π/4 of the light.
#[test]
fn erase_and_reshape_cut_the_mask() {
    let ops = [PaintOp::Erase { points: vec![[0.1, 0.1]], radius: 0.05, hardness: 1.0 }];
    let t = render(&ops, 64, &mut no_files).unwrap();
    let k = 6 * 64 + 6;
    assert_eq!((t.mask[k], t.radiance[k], t.emission()[k]), (0.0, [1.0; 3], [0.0; 3]));
    let t = render(&[PaintOp::Reshape { shape: Shape::Disc }], 128, &mut no_files).unwrap();
    let kept = t.mask.iter().sum::<f64>() / t.mask.len() as f64;
    assert!((kept - std::f64::consts::FRAC_PI_4).abs() < 0.01, "{kept}");
}

/// A blur keeps a constant field, and spreads a lone bright texel with the requested
/// standard deviation (its second moment, in texels).
#[test]
fn blur_spreads_by_its_sigma() {
    let flat = render(&[PaintOp::Blur { sigma: 0.05 }], 32, &mut no_files).unwrap();
    assert!(flat.radiance.iter().all(|c| c.iter().all(|v| (v - 1.0).abs() < 1e-12)));
    let side = 64;
    let ops = [
        PaintOp::Fill { colour: [0.0; 3], intensity: 1.0 },
        dab([32.5 / 64.0, 32.5 / 64.0], 0.3 / 64.0, 1.0, [1.0; 3], Blend::Mix),
        PaintOp::Blur { sigma: 3.0 / 64.0 },
    ];
    let t = render(&ops, side, &mut no_files).unwrap();
    let total: f64 = t.radiance.iter().map(|c| c[0]).sum();
    let variance: f64 =
        t.radiance.iter().enumerate().map(|(k, c)| c[0] * (((k % side) as f64 - 32.0).powi(2))).sum::<f64>() / total;
    assert!((total - 1.0).abs() < 1e-9, "energy {total}");
    assert!((variance.sqrt() - 3.0).abs() < 0.05, "sigma {}", variance.sqrt());
}

/// Warps move, scale and turn the content; imports average the image over each texel.
#[test]
fn warps_and_imports() {
    let mark = dab([0.25, 0.25], 0.06, 1.0, [5.0, 5.0, 5.0], Blend::Mix);
    let value = |t: &LightTexture, u: f64, v: f64| t.radiance[(v * 32.0) as usize * 32 + (u * 32.0) as usize][0];
    let moved =
        render(&[mark.clone(), PaintOp::Warp { offset: [0.5, 0.25], scale: 1.0, angle: 0.0 }], 32, &mut no_files)
            .unwrap();
    assert_eq!((value(&moved, 0.75, 0.5), value(&moved, 0.25, 0.25)), (5.0, 0.0));
    let turned =
        render(&[mark.clone(), PaintOp::Warp { offset: [0.0; 2], scale: 1.0, angle: 90.0 }], 32, &mut no_files)
            .unwrap();
    assert_eq!(value(&turned, 0.75, 0.25), 5.0, "a quarter turn takes (¼, ¼) to (¾, ¼)");
    let shrunk =
        render(&[mark, PaintOp::Warp { offset: [0.0; 2], scale: 0.5, angle: 0.0 }], 32, &mut no_files).unwrap();
    assert_eq!(
        (value(&shrunk, 0.36, 0.36), value(&shrunk, 0.05, 0.05)),
        (5.0, 0.0),
        "halved about the centre: (¼, ¼) to (⅜, ⅜)"
    );

    let mut load = |path: &str| -> Result<Image, String> {
        assert_eq!(path, "window.exr");
        Ok(Image { width: 2, height: 2, pixels: vec![[1.0; 3], [2.0; 3], [3.0; 3], [4.0; 3]] })
    };
    let t = render(&[PaintOp::Import { path: "window.exr".into(), intensity: 2.0 }], 32, &mut load).unwrap();
    assert_eq!(
        [value(&t, 0.1, 0.1), value(&t, 0.9, 0.1), value(&t, 0.1, 0.9), value(&t, 0.9, 0.9)],
        [2.0, 4.0, 6.0, 8.0]
    );
}

/// Bad operations and sizes are refused with the problem named; replay is deterministic.
#[test]
fn bad_logs_are_refused_and_replay_is_deterministic() {
    let refused = |ops: &[PaintOp]| render(ops, 32, &mut no_files).unwrap_err();
    assert!(refused(&[dab([0.5, f64::NAN], 0.1, 1.0, [1.0; 3], Blend::Mix)]).contains("stroke point"));
    assert!(refused(&[dab([0.5, 0.5], 50.0, 1.0, [1.0; 3], Blend::Mix)]).contains("brush radius"));
    assert!(refused(&[PaintOp::Fill { colour: [-1.0, 0.0, 0.0], intensity: 1.0 }]).contains("within 0..=1e6"));
    assert!(refused(&[PaintOp::Warp { offset: [0.0; 2], scale: 0.0, angle: 0.0 }]).contains("warp scale"));
    assert!(refused(&[PaintOp::Import { path: "gone.exr".into(), intensity: 1.0 }]).contains("no file gone.exr"));
    let long = vec![PaintOp::Blur { sigma: 0.0 }; MAX_OPERATIONS + 1];
    assert!(refused(&long).contains("operations"));
    assert!(render(&[], 48, &mut no_files).unwrap_err().contains("not 48"));
    // Each operation within bounds, the whole too slow to replay: refused before any work.
    let heavy = vec![PaintOp::Blur { sigma: 1.0 }; 400];
    assert!(render(&heavy, 128, &mut no_files).unwrap_err().contains("too long to replay"));
    // Colours beyond range are refused; the largest allowed stay finite where the brush
    // does not reach (0 × ∞ would be NaN).
    assert!(refused(&[dab([0.5, 0.5], 0.1, 1.0, [1e303, 1.0, 1.0], Blend::Mix)]).contains("within 0..=1e6"));
    let bright = PaintOp::Stroke {
        points: vec![[0.5, 0.5]],
        radius: 0.1,
        hardness: 1.0,
        colour: [1e6; 3],
        intensity: 1e6,
        blend: Blend::Multiply,
    };
    let t = render(&[PaintOp::Fill { colour: [0.0; 3], intensity: 1.0 }, bright], 32, &mut no_files).unwrap();
    assert!(t.radiance.iter().flatten().all(|v| v.is_finite()));
    // Values that would overflow stay finite.
    let huge = PaintOp::Fill { colour: [1e6; 3], intensity: 1e6 };
    let t = render(&[huge.clone(), huge], 32, &mut no_files).unwrap();
    assert!(t.radiance.iter().flatten().all(|v| v.is_finite()));
    let ops = [
        PaintOp::Fill { colour: [0.2, 0.4, 1.0], intensity: 3.0 },
        PaintOp::Stroke {
            points: (0..50).map(|i| [0.1 + 0.016 * i as f64, 0.5]).collect(),
            radius: 0.08,
            hardness: 0.3,
            colour: [1.0, 0.8, 0.2],
            intensity: 10.0,
            blend: Blend::Add,
        },
        PaintOp::Blur { sigma: 0.02 },
    ];
    assert_eq!(render(&ops, 64, &mut no_files).unwrap(), render(&ops, 64, &mut no_files).unwrap());
}
