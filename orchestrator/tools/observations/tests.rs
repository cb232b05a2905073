use super::*;

const GOOD: &str = "# glint observations v1\n# truth_rate_deg_per_frame = 0,0.25,0\nwindow,frame_index,t_s,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z,range_m,flux_650,flux_700\nstable,0,0.0,1,0,0,0,0,1,2.1e6,1e-14,2e-14\nmotion,0,10.0,1,0,0,0,0,1,2.1e6,3e-14,4e-14\n";

#[test]
fn parses_windows_bands_and_truth() {
    let f = parse(GOOD, "obs.csv").unwrap();
    assert_eq!(f.set.wavelengths_nm, vec![650.0, 700.0]);
    assert_eq!((f.set.stable.len(), f.set.motion.len()), (1, 1));
    assert_eq!(f.set.motion[0].flux_w, vec![3e-14, 4e-14]);
    assert_eq!(f.truth_rate_deg_per_frame, Some([0.0, 0.25, 0.0]));
}

#[test]
fn errors_name_file_line_and_column() {
    let bad = GOOD.replace("stable,0,0.0,1,0,0", "stable,0,0.0,2,0,0");
    let e = parse(&bad, "obs.csv").err().unwrap().to_string();
    assert!(e.contains("obs.csv:4") && e.contains("sun_x"), "{e}");
    let bad = GOOD.replace("1e-14,2e-14", "1e-14,abc");
    let e = parse(&bad, "obs.csv").err().unwrap().to_string();
    assert!(e.contains("obs.csv:4") && e.contains("flux_700"), "{e}");
    let bad = GOOD.replace("motion,0", "moving,0");
    let e = parse(&bad, "obs.csv").err().unwrap().to_string();
    assert!(e.contains("window") && e.contains("moving"), "{e}");
}

fn error(text: &str) -> String {
    parse(text, "obs.csv").err().expect("refused").to_string()
}

/// Another tool's light curve: no σ columns, Gaussian noise of 3e-16 W about a faint
/// curve, so some fluxes are negative. Read, with σ estimated near the noise; a flux far
/// below any such noise is refused, naming its line, the column and the σ used.
#[test]
fn without_sigma_columns_noise_below_zero_is_read_and_sigma_estimated() {
    let sigma = 3e-16;
    let mut state = 7u64;
    let mut gauss = || {
        let mut u = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (a, b) = (u(), u());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    };
    let mut text = String::from(
        "window,frame_index,t_s,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z,range_m,flux_500\n",
    );
    for window in ["stable", "motion"] {
        for k in 0..200 {
            let flux = 4e-16 * (1.0 + (k as f64 * 0.03).sin()) + sigma * gauss();
            text += &format!("{window},{k},{k}.0,1,0,0,0,0,1,2.1e6,{flux:e}\n");
        }
    }
    let negatives = text.lines().filter(|l| l.contains(",-")).count();
    assert!(negatives > 10, "{negatives}");
    let f = parse(&text, "other.csv").expect("read");
    let [stable, motion] = f.estimated_sigma_w.expect("σ estimated");
    for s in [stable[0], motion[0]] {
        assert!((s / sigma - 1.0).abs() < 0.15, "σ̂ {s}");
    }
    assert!(f.set.motion.iter().all(|o| o.sigma_w.is_empty()));
    // line 1 is the header: frame 40 of the motion window is on line 242
    let far = (text.lines())
        .map(|l| {
            if l.starts_with("motion,40,") {
                "motion,40,40.0,1,0,0,0,0,1,2.1e6,-1e-13".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let e = format!("{:#}", parse(&far, "other.csv").err().expect("refused"));
    assert!(
        e.contains("other.csv:242")
            && e.contains("flux_500")
            && e.contains("estimated from the light curve")
            && e.contains("sigma_*"),
        "{e}"
    );
}

/// The gaps an adversarial probe found: each is refused with line and column.
#[test]
fn malformed_bands_frames_and_noise_are_refused_with_line_and_column() {
    let header =
        "window,frame_index,t_s,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z,range_m,flux_650,flux_700";
    let e = error(&GOOD.replace(header, &header.replace("flux_700", "flux_nan")));
    assert!(
        e.contains("obs.csv:3") && e.contains("flux_nan") && e.contains("200..=25000"),
        "{e}"
    );
    let e = error(&GOOD.replace(header, &header.replace("flux_700", "flux_1000000")));
    assert!(
        e.contains("flux_1000000") && e.contains("200..=25000"),
        "{e}"
    );
    let e = error(&GOOD.replace(header, &header.replace("flux_700", "flux_650")));
    assert!(
        e.contains("columns 11 (`flux_650`) and 12 (`flux_650`) are the same band"),
        "{e}"
    );
    let e = error(
        &GOOD
            .replace(header, &header.replace("t_s", "time"))
            .replace("sun_x", "t"),
    );
    assert!(e.contains("are both `t_s`"), "{e}");
    let e = error(&GOOD.replace("motion,0,10.0", "motion,18446744073709551615,10.0"));
    assert!(
        e.contains("obs.csv:5") && e.contains("frame_index") && e.contains("0..=1000000000"),
        "{e}"
    );
    let e = error(&GOOD.replace("3e-14,4e-14", "-3e-14,4e-14"));
    assert!(
        e.contains("obs.csv:5") && e.contains("flux_650") && e.contains("negative"),
        "{e}"
    );
    let noisy = GOOD
        .replace(",flux_700\n", ",flux_700,sigma_650,sigma_700\n")
        .replace("1e-14,2e-14\n", "1e-14,2e-14,1e-16,1e-16\n")
        .replace("3e-14,4e-14\n", "3e-14,4e-14,1e-16,1e-16\n");
    assert!(parse(&noisy, "obs.csv").is_ok());
    // Noise about a faint flux may dip below zero; far below is not noise.
    assert!(parse(&noisy.replace("3e-14,4e-14,", "-2e-16,4e-14,"), "obs.csv").is_ok());
    let e = error(&noisy.replace("3e-14,4e-14,", "-1e-15,4e-14,"));
    assert!(e.contains("obs.csv:5") && e.contains("flux_650"), "{e}");
    for bad in ["-1e-16", "0"] {
        let e = error(&noisy.replace(
            "3e-14,4e-14,1e-16,1e-16",
            &format!("3e-14,4e-14,{bad},1e-16"),
        ));
        assert!(
            e.contains("obs.csv:5") && e.contains("sigma_650") && e.contains("> 0"),
            "{bad}: {e}"
        );
    }
}

/// A light curve from another tool: a UTF-8 byte-order mark, other spellings, another
/// column order, and columns glint does not read (named back to the user).
#[test]
fn columns_are_read_by_name_in_any_order() {
    let text = "\u{feff}# from another tool\nframe,t,Window,phase_deg,sx,sy,sz,ox,oy,oz,range,flux_700,flux_650,err_650,err_700\n\
        0,0.0,stable,12.5,1,0,0,0,0,1,2.1e6,2e-14,1e-14,1e-16,2e-16\n\
        0,10.0,motion,12.6,1,0,0,0,0,1,2.1e6,4e-14,3e-14,1e-16,2e-16\n";
    let f = parse(text, "lc.csv").unwrap();
    assert_eq!(f.set.wavelengths_nm, vec![700.0, 650.0]);
    assert_eq!(f.set.motion[0].flux_w, vec![4e-14, 3e-14]);
    assert_eq!(f.set.motion[0].sigma_w, vec![2e-16, 1e-16]);
    assert_eq!(f.set.motion[0].t_s, 10.0);
    assert_eq!(f.ignored_columns, vec!["phase_deg".to_string()]);
    let e = error(&GOOD.replace("range_m,", "distance,"));
    assert!(
        e.contains("no `range_m` column (also read as: range, r_m)"),
        "{e}"
    );
}

#[test]
fn comments_blank_lines_and_crlf_keep_line_numbers() {
    let text = GOOD.replace('\n', "\r\n").replacen(
        "window,",
        "\r\n  # an indented comment, with \"quotes\r\n\r\nwindow,",
        1,
    );
    let f = parse(&text, "obs.csv").unwrap();
    assert_eq!((f.set.stable.len(), f.set.motion.len()), (1, 1));
    assert_eq!(f.truth_rate_deg_per_frame, Some([0.0, 0.25, 0.0]));
    let bad = text.replace("motion,0,10.0", "motion,x,10.0");
    let e = parse(&bad, "obs.csv").err().unwrap().to_string();
    assert!(
        e.contains("obs.csv:8") && e.contains("frame_index") && e.contains("whole number"),
        "{e}"
    );
    let bad = text.replace("motion,0,10.0", "motion,0,inf");
    let e = parse(&bad, "obs.csv").err().unwrap().to_string();
    assert!(e.contains("obs.csv:8") && e.contains("t_s"), "{e}");
    let bad = text.replace("window,frame_index", "win,frame_index");
    let e = parse(&bad, "obs.csv").err().unwrap().to_string();
    assert!(e.contains("obs.csv:6") && e.contains("header"), "{e}");
    let bad = text.replace("2e-14\r\n", "2e-14,5\r\n");
    let e = parse(&bad, "obs.csv").err().unwrap().to_string();
    assert!(e.contains("obs.csv:7") && e.contains("13 values"), "{e}");
}

#[test]
fn exported_spectra_read_back_to_the_bit() {
    let mut sp = Spectrum {
        n_bands: 2,
        window: Window::Stable as u32,
        sun_body: [0.6, 0.0, 0.8],
        observer_body: [0.0, 1.0, 0.0],
        range_m: 2_146_000.123,
        ..Default::default()
    };
    sp.meta.t_ns = 18_437_087_945;
    sp.wavelength_nm[..2].copy_from_slice(&[650.0, 700.0]);
    sp.flux_w[..2].copy_from_slice(&[1.234_567_890_123e-14, 2.0 / 3.0 * 1e-14]);
    sp.sigma_w[..2].copy_from_slice(&[1e-16, 3e-16]);
    let motion = Spectrum {
        window: Window::Motion as u32,
        frame_index: 3,
        ..sp
    };
    let dir = std::env::temp_dir().join(format!("glint-obs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("observations.csv");
    write(&path, &[sp, motion], Some([0.0, 0.25, 0.0])).unwrap();
    let f = read(&path).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let o = &f.set.motion[0];
    assert_eq!(o.frame_index, 3);
    assert_eq!(o.flux_w, sp.flux_w[..2].to_vec());
    assert_eq!(o.sigma_w, sp.sigma_w[..2].to_vec());
    assert_eq!(o.range_m, sp.range_m);
    assert_eq!(o.t_s, sp.meta.t_ns as f64 * 1e-9);
    assert_eq!(f.set.wavelengths_nm, vec![650.0, 700.0]);
    assert_eq!(f.truth_rate_deg_per_frame, Some([0.0, 0.25, 0.0]));
}
