use super::*;

fn spec(command: &[&str], map: &str) -> MapperSpec {
    MapperSpec {
        name: "mine".into(),
        command: command
            .iter()
            .map(std::string::ToString::to_string)
            .collect(),
        map: map.into(),
        timeout_s: None,
    }
}

#[test]
fn a_mapper_table_is_checked_before_any_run() {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let ok = spec(&["graph2tree", "-i", "{scans}"], "{dir}/map.bt.ot")
        .check(&base, &["ray_update"], false)
        .unwrap();
    assert_eq!(ok.timeout, Duration::from_secs(300));
    let err = |s: MapperSpec, taken: &[&str]| s.check(&base, taken, false).unwrap_err();
    assert!(err(spec(&["x", "{scan}"], "m.bt"), &[]).contains("unknown placeholder {scan}"));
    assert!(err(spec(&["x", "{scans"], "m.bt"), &[]).contains("does not close"));
    assert!(err(spec(&[], "m.bt"), &[]).contains("must name a program"));
    assert!(err(spec(&["x"], ""), &[]).contains("`map`"));
    assert!(err(spec(&["x"], "m.bt"), &["mine"]).contains("already a method"));
    let mut named = spec(&["x"], "m.bt");
    named.name = "my mapper".into();
    assert!(err(named, &[]).contains("letters, digits"));
    for timeout in [0.0, -1.0, f64::NAN, 1e9] {
        let mut slow = spec(&["x"], "m.bt");
        slow.timeout_s = Some(timeout);
        assert!(err(slow, &[]).contains("timeout_s"), "{timeout}");
    }
}

#[test]
fn a_script_beside_the_experiment_is_passed_by_its_absolute_path() {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let mapper = spec(
        &["python3", "../mappers/ray_mapper.py", "{scans}"],
        "{dir}/m.ot",
    )
    .check(&base, &[], false)
    .unwrap();
    let script = PathBuf::from(&mapper.command[1]);
    assert!(script.is_absolute() && script.ends_with("mappers/ray_mapper.py"));
    assert_eq!(mapper.command[2], "{scans}");
    // The script is an input of the fingerprint beside the program.
    let missing = spec(&["no-such-mapper-anywhere"], "m.bt")
        .check(&base, &[], false)
        .unwrap();
    let e = missing.program().unwrap_err().to_string();
    assert!(
        e.contains("'no-such-mapper-anywhere' is not on PATH"),
        "{e}"
    );
    let sh = spec(&["sh", "../mappers/ray_mapper.py"], "m.bt")
        .check(&base, &[], false)
        .unwrap();
    let inputs = sh.inputs().unwrap();
    assert!(inputs.contains(&script) && inputs.len() == 2, "{inputs:?}");
}

#[test]
fn placeholders_become_the_runs_paths_and_numbers() {
    let places = Placeholders {
        scans: "/s/scans.graph".into(),
        poses: "/s/poses.txt".into(),
        plys: "/s".into(),
        dir: "/w".into(),
        resolution: 0.01,
        max_range: 2.0,
        seed: 7,
        camera: None,
    };
    assert_eq!(
        places.fill("{dir}/map_{seed}.bt {scans} {poses} {plys} {resolution} {max_range}"),
        "/w/map_7.bt /s/scans.graph /s/poses.txt /s 0.01 2"
    );
    // A depth camera's: its images' folder (the export's) and intrinsics.
    let camera = Placeholders {
        camera: Some(DepthCamera {
            fx: 111.5,
            fy: 111.5,
            cx: 105.5,
            cy: 59.5,
            scale: 5000.0,
        }),
        ..places
    };
    assert_eq!(
        camera.fill("{depth}/depth.txt {intrinsics} {depth_scale}"),
        "/s/depth.txt 111.5,111.5,105.5,59.5 5000"
    );
}

#[test]
fn a_depth_cameras_placeholders_need_a_depth_camera() {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    for placeholder in DEPTH_PLACEHOLDERS {
        let mapper = spec(&["x", placeholder], "m.ot");
        let e = mapper.clone().check(&base, &[], false).unwrap_err();
        assert!(e.contains("needs a depth camera's images"), "{e}");
        assert!(mapper.check(&base, &[], true).is_ok(), "{placeholder}");
    }
}

#[test]
fn only_the_end_of_a_huge_stderr_is_read() {
    // A sparse 64 GiB stderr (NULs) ending in a message: reading it whole
    // would exhaust memory; its tail is the message, on one line, with no
    // control characters.
    let dir = std::env::temp_dir().join(format!("sigmap-stderr-tail-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("stderr.txt");
    let file = std::fs::File::create(&path).unwrap();
    let length = 64 << 30;
    file.set_len(length).unwrap();
    let message = b"\nerror: the mapper\nran out of points\n";
    std::os::unix::fs::FileExt::write_at(&file, message, length).unwrap();
    assert_eq!(stderr_tail(&path), "error: the mapper ran out of points");
    let short = dir.join("short.txt");
    std::fs::write(&short, "x".repeat(STDERR_TAIL + 5) + " end").unwrap();
    let tail = stderr_tail(&short);
    assert_eq!(tail.len(), STDERR_TAIL);
    assert!(tail.ends_with("x end"));
    assert_eq!(stderr_tail(&dir.join("missing.txt")), "");
    std::fs::remove_dir_all(&dir).unwrap();
}
