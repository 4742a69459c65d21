//! `report.html` rendered by a real browser: Debian's headless Chromium
//! (`apt-get install chromium`; `.ci/run` installs it) opens the page a
//! `sigmap run` wrote, takes a screenshot, and the screenshot must show the
//! charts (the slice's colours, the tables' text), with nothing fetched.

mod common;

use common::{portable_quickstart, sigmap_ok};
use std::path::Path;
use std::process::Command;

/// Runs Chromium as the machine's probe starts it (headless, no sandbox as
/// root, no background networking on the closed network, a fresh profile)
/// with `args`, checks it succeeded, and returns its stdout. A browser that
/// exits with an error is started once more (a CI run saw one exit in two
/// seconds with nothing on stderr); a second failure fails the test with
/// both exit statuses and stderrs.
fn chromium(profile: &Path, args: &[&str]) -> String {
    let run = || {
        Command::new("chromium")
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--hide-scrollbars",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .args(args)
            .output()
            .expect("run chromium")
    };
    let first = run();
    if first.status.success() {
        return String::from_utf8_lossy(&first.stdout).into_owned();
    }
    let second = run();
    assert!(
        second.status.success(),
        "chromium {args:?} failed twice: {} ({}), then {} ({})",
        first.status,
        String::from_utf8_lossy(&first.stderr),
        second.status,
        String::from_utf8_lossy(&second.stderr)
    );
    String::from_utf8_lossy(&second.stdout).into_owned()
}

/// Pixels of `png` within 6 of `rgb` in every channel.
fn count_colour(pixels: &[u8], channels: usize, rgb: [u8; 3]) -> usize {
    pixels
        .chunks_exact(channels)
        .filter(|p| (0..3).all(|i| p[i].abs_diff(rgb[i]) <= 6))
        .count()
}

#[test]
#[ignore = "needs Debian's chromium (apt-get install chromium); .ci/run runs it"]
fn the_report_renders_in_headless_chromium() {
    assert!(
        Command::new("chromium").arg("--version").output().is_ok(),
        "chromium not found (apt-get install chromium; `bash .ci/run` does)"
    );
    let dir = tempfile::tempdir().unwrap();
    // The quickstart on two seeds with a two-value sweep: every kind of chart.
    let experiment = dir.path().join("report.toml");
    let text = portable_quickstart()
        .replacen("seeds = [1, 2, 3]", "seeds = [1, 2]", 1)
        .replacen(
            "[robot]",
            "[[sweep]]\nfield = \"pose_error_scale\"\nvalues = [0.0, 1.0]\n\n[robot]",
            1,
        );
    std::fs::write(&experiment, text).unwrap();
    let out = dir.path().join("results");
    sigmap_ok(&[
        "run",
        experiment.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let report = out.join("report.html");
    let html = std::fs::read_to_string(&report).unwrap();

    // Self-contained: every chart of the folder inline, nothing to fetch.
    let mut charts = 0;
    for entry in std::fs::read_dir(&out).unwrap().flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".svg") {
            let svg = std::fs::read_to_string(entry.path()).unwrap();
            assert!(html.contains(svg.trim_end()), "{name} is not inline");
            charts += 1;
        }
    }
    assert!(charts >= 4, "{charts} charts"); // scores, score_*, coverage, slice
    assert_eq!(html.matches("<svg").count(), charts);
    for fetch in ["src=", "href=", "url(", "@import", "https:"] {
        assert!(!html.contains(fetch), "the page would fetch: {fetch}");
    }
    let without_namespace = html.replace("xmlns=\"http://www.w3.org/2000/svg\"", "");
    assert!(!without_namespace.contains("http:"), "a network address");
    let fingerprint = std::fs::read_to_string(out.join("run.toml"))
        .unwrap()
        .lines()
        .find_map(|l| {
            l.strip_prefix("fingerprint = \"")
                .map(|f| f.trim_end_matches('"').to_owned())
        })
        .unwrap();
    assert!(html.contains(&fingerprint), "the input fingerprint");

    // The browser's DOM holds the figures and the headline tables.
    let profile = dir.path().join("chromium");
    let url = format!("file://{}", report.display());
    let dom = chromium(&profile, &["--dump-dom", &url]);
    assert_eq!(dom.matches("<figure").count(), charts);
    assert_eq!(
        dom.matches("<table class=\"headline\"").count(),
        2,
        "one per cell"
    );

    // The screenshot: not blank, and the slice's colours are on it (the
    // charts were drawn, not just parsed). The window is tall enough to
    // reach the slice below the headline and consistency tables.
    let shot = dir.path().join("report.png");
    chromium(
        &profile,
        &[
            "--window-size=1400,3400",
            &format!("--screenshot={}", shot.display()),
            &url,
        ],
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    let pixels = &pixels[..info.buffer_size()];
    let channels = info.color_type.samples();
    assert!(channels >= 3, "{:?}", info.color_type);
    let total = pixels.len() / channels;
    let white = count_colour(pixels, channels, [255, 255, 255]);
    let ink = count_colour(pixels, channels, [34, 34, 34]); // the page's text
    let free = count_colour(pixels, channels, [205, 225, 245]); // slice: free, correct
    let false_free = count_colour(pixels, channels, [220, 30, 30]); // slice: false-free
    eprintln!(
        "{}x{}: {total} px, {white} white, {ink} text, {free} free-cell, {false_free} false-free",
        info.width, info.height
    );
    assert!(white < total * 95 / 100, "blank page");
    assert!(ink > 1000, "no text drawn");
    assert!(free > 20_000, "the slice is not drawn");
    assert!(
        false_free > 100,
        "the slice's false-free cells are not drawn"
    );
}
