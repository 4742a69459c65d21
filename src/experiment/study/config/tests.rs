use super::file::{PoolingSpec, RiskSpec, SeedsSpec, SwitchSpec};
use super::*;
use crate::mapping::pooling::Pooling;
use crate::mapping::settings::{MapSettings, OpdfDefaults, SampleGate};

#[test]
fn grid_offsets_are_sub_voxel_per_seed_and_zero_when_off() {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/quickstart.toml"
    ));
    let mut experiment = Experiment::load(path).unwrap();
    assert!(!experiment.grid_offset);
    assert_eq!(experiment.map_offset(1), Vector3::zeros());
    experiment.grid_offset = true;
    let res = experiment.resolution;
    let offsets: Vec<Vector3> = (1..=20).map(|s| experiment.map_offset(s)).collect();
    for o in &offsets {
        assert!(o.iter().all(|c| (0.0..res).contains(c)), "{o:?}");
    }
    assert_eq!(experiment.map_offset(3), offsets[2], "reproducible");
    for (i, a) in offsets.iter().enumerate() {
        for b in &offsets[i + 1..] {
            assert!((a - b).amax() > 0.0, "two seeds share an offset");
        }
    }
    // Spread over the cell, not stuck in a corner: each axis's mean near res/2.
    let mean = offsets.iter().sum::<Vector3>() / 20.0;
    assert!(
        mean.iter().all(|c| (0.3 * res..0.7 * res).contains(c)),
        "{mean:?}"
    );
}

#[test]
fn interpolate_beams_reads_a_switch_or_on_and_off() {
    #[derive(Deserialize)]
    struct File {
        interpolate_beams: SwitchSpec,
    }
    let read = |text: &str| {
        toml::from_str::<File>(text)
            .unwrap()
            .interpolate_beams
            .on("interpolate_beams")
    };
    assert_eq!(read("interpolate_beams = true"), Ok(true));
    assert_eq!(read("interpolate_beams = \"on\""), Ok(true));
    assert_eq!(read("interpolate_beams = \"off\""), Ok(false));
    assert!(read("interpolate_beams = \"yes\"")
        .unwrap_err()
        .starts_with("interpolate_beams = \"yes\": use true"));
}

#[test]
fn beam_pooling_reads_a_switch_or_a_mode() {
    #[derive(Deserialize)]
    struct File {
        beam_pooling: PoolingSpec,
    }
    let read = |text: &str| toml::from_str::<File>(text).unwrap().beam_pooling.pooling();
    assert_eq!(read("beam_pooling = false"), Ok(Pooling::Off));
    assert_eq!(read("beam_pooling = true"), Ok(Pooling::Windows));
    assert_eq!(read("beam_pooling = \"faces\""), Ok(Pooling::Faces));
    assert_eq!(read("beam_pooling = \"windows\""), Ok(Pooling::Windows));
    assert_eq!(read("beam_pooling = \"off\""), Ok(Pooling::Off));
    let error = read("beam_pooling = \"face\"").unwrap_err();
    assert!(
        error.starts_with("beam_pooling = \"face\": use \"faces\""),
        "{error}"
    );
}

#[test]
fn beam_pooling_is_a_string_sweep_axis() {
    let text = crate::experiment::portable_quickstart()
        .replacen("seed = 1", "seed = 1\nbeam_pooling = \"off\"", 1)
        + "\n[[sweep]]\nfield = \"experiment.beam_pooling\"\nvalues = [\"off\", \"faces\", \"windows\"]\n";
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pooling.toml");
    std::fs::write(&path, text).unwrap();
    let experiment = Experiment::load(&path).unwrap();
    let modes: Vec<Pooling> = experiment
        .cells()
        .iter()
        .map(|cell| Experiment::load_cell(&path, cell).unwrap().map.beam_pooling)
        .collect();
    assert_eq!(modes, [Pooling::Off, Pooling::Faces, Pooling::Windows]);
}

/// The quickstart with `edit` applied, written to `dir`, and loaded: the
/// map settings of each of its sweep cells.
fn quickstart_settings(dir: &Path, edit: impl Fn(String) -> String) -> Vec<MapSettings> {
    let text = crate::experiment::portable_quickstart();
    let path = dir.join("settings.toml");
    std::fs::write(&path, edit(text)).unwrap();
    let experiment = Experiment::load(&path).unwrap();
    experiment
        .cells()
        .iter()
        .map(|cell| Experiment::load_cell(&path, cell).unwrap().map)
        .collect()
}

#[test]
fn left_out_settings_are_the_measured_defaults_and_the_ray_update_stays_octomap() {
    let dir = tempfile::tempdir().unwrap();
    let defaults = OpdfDefaults::MEASURED;
    let [map] = &quickstart_settings(dir.path(), |t| t)[..] else {
        panic!("one cell")
    };
    assert_eq!(map.beam_pooling, defaults.beam_pooling);
    assert_eq!(map.interpolate_beams, defaults.interpolate_beams);
    assert_eq!(map.model.risk, defaults.risk);
    assert_eq!(
        (map.ray_pooling, map.sample_gate),
        (Pooling::Off, SampleGate::default())
    );
    // Set in the file: every method pools alike; each opt-out holds.
    let set = |line: &'static str| {
        move |t: String| t.replacen("seed = 1", &format!("seed = 1\n{line}"), 1)
    };
    let [map] = &quickstart_settings(dir.path(), set("beam_pooling = \"faces\""))[..] else {
        panic!("one cell")
    };
    assert_eq!(
        (map.beam_pooling, map.ray_pooling),
        (Pooling::Faces, Pooling::Faces)
    );
    let [map] = &quickstart_settings(dir.path(), set("beam_pooling = \"off\""))[..] else {
        panic!("one cell")
    };
    assert_eq!(
        (map.beam_pooling, map.ray_pooling),
        (Pooling::Off, Pooling::Off)
    );
    let [map] = &quickstart_settings(dir.path(), set("interpolate_beams = \"off\""))[..] else {
        panic!("one cell")
    };
    assert!(!map.interpolate_beams);
    let [map] = &quickstart_settings(dir.path(), set("sample_gate = \"range*6\""))[..] else {
        panic!("one cell")
    };
    assert_eq!(map.sample_gate, SampleGate::from_name("range*6").unwrap());
    // The risk level is a number or "off", and a sweep may take both.
    let risks: Vec<Option<f64>> = quickstart_settings(dir.path(), |t| {
        set("risk = \"off\"")(t)
            + "\n[[sweep]]\nfield = \"experiment.risk\"\nvalues = [\"off\", 0.5, 0.1]\n"
    })
    .iter()
    .map(|m| m.model.risk)
    .collect();
    assert_eq!(risks, [None, Some(0.5), Some(0.1)]);
}

#[test]
fn samples_left_to_the_default_stay_off_for_a_raster_too_dense_to_sample() {
    // 1001 x 801 beams a viewpoint: more than the samples' budget
    // (`check_sample_budget`), so the default leaves them off rather than
    // refuse the experiment; asked for, they are refused.
    let dir = tempfile::tempdir().unwrap();
    let dense = |t: String| {
        t.replace("horizontal_step_deg = 0.5", "horizontal_step_deg = 0.05")
            .replace("vertical_step_deg = 0.5", "vertical_step_deg = 0.05")
    };
    let [map] = &quickstart_settings(dir.path(), dense)[..] else {
        panic!("one cell")
    };
    assert!(!map.interpolate_beams);
    assert_eq!(map.beam_pooling, OpdfDefaults::MEASURED.beam_pooling);
    let loaded = Experiment::load(&dir.path().join("settings.toml")).unwrap();
    assert_eq!(loaded.samples_over_budget(), Some(801_801));
    let path = dir.path().join("asked.toml");
    let text = std::fs::read_to_string(dir.path().join("settings.toml")).unwrap();
    std::fs::write(
        &path,
        text.replacen("seed = 1", "seed = 1\ninterpolate_beams = \"on\"", 1),
    )
    .unwrap();
    let error = Experiment::load(&path).err().unwrap().to_string();
    assert!(
        error.contains("interpolate_beams: 801801 beams per viewpoint"),
        "{error}"
    );
    let [_] = &quickstart_settings(dir.path(), |t| t)[..] else {
        panic!("one cell")
    };
    let quickstart = Experiment::load(&dir.path().join("settings.toml")).unwrap();
    assert_eq!(quickstart.samples_over_budget(), None);
}

#[test]
fn a_dense_raster_is_not_refused_for_its_observable_mask() {
    // 1001 x 801 beams at 0.05° from six viewpoints, out to 2 m at 1 cm:
    // 9.6e8 steps, but their cells lie in the six 4 m cubes (3.8e8 cells).
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dense.toml");
    let text = crate::experiment::portable_quickstart()
        .replace("horizontal_step_deg = 0.5", "horizontal_step_deg = 0.05")
        .replace("vertical_step_deg = 0.5", "vertical_step_deg = 0.05");
    std::fs::write(&path, text).unwrap();
    let experiment = Experiment::load(&path).unwrap();
    experiment.check_truth_cost().unwrap();
    // At 5 mm the cubes hold 3.1e9 cells and the steps are 1.9e9: refused.
    std::fs::write(
        &path,
        std::fs::read_to_string(&path)
            .unwrap()
            .replace("resolution = 0.01", "resolution = 0.005"),
    )
    .unwrap();
    let error = Experiment::load(&path)
        .unwrap()
        .check_truth_cost()
        .unwrap_err()
        .to_string();
    assert!(error.contains("holds at most 5e8"), "{error}");
}

#[test]
fn sweep_cells_and_overrides() {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/consistency.toml"
    ));
    let experiment = Experiment::load(path).unwrap();
    let cells = experiment.cells();
    assert_eq!(cells.len(), 3);
    let stressed = Experiment::load_cell(path, &cells[2]).unwrap();
    assert_eq!(stressed.profile.name, "stressed");
    assert_eq!(
        Experiment::cell_label(&cells[0]),
        "experiment.error_profile=profiles/industrial.toml"
    );
    let number = [(
        "experiment.sensor.max_range".to_string(),
        SweepValue::Number(1.5),
    )];
    assert_eq!(
        Experiment::load_cell(path, &number)
            .unwrap()
            .scanner
            .max_range,
        1.5
    );
    let wrong = [(
        "experiment.sensor.max_range".to_string(),
        SweepValue::Text("far".into()),
    )];
    let msg = Experiment::load_cell(path, &wrong)
        .err()
        .unwrap()
        .to_string();
    assert!(
        msg.contains("holds float") && msg.contains("string"),
        "{msg}"
    );
    let scale = [("pose_error_scale".to_string(), SweepValue::Number(2.0))];
    let scaled = Experiment::load_cell(path, &scale).unwrap();
    assert!(
        (scaled.profile.world_from_scene[(0, 0)]
            - 4.0 * experiment.profile.world_from_scene[(0, 0)])
            .abs()
            < 1e-18
    );
}

/// What an experiment file may leave out takes the defaults docs/files.md
/// documents ("Experiment file").
#[test]
fn a_minimal_file_takes_the_documented_defaults() {
    let text = r#"
        scene = "s.toml"
        error_profile = "p.toml"
        [robot]
        urdf = "r.urdf"
        flange_link = "tool0"
        [sensor]
        horizontal_fov_deg = 50.0
        horizontal_step_deg = 0.5
        min_range = 0.1
        max_range = 2.0
    "#;
    let file: super::file::ExperimentFile = toml::from_str(text).unwrap();
    assert_eq!(file.name, None);
    assert_eq!(file.description, "");
    assert_eq!(file.seed, 1);
    assert_eq!(file.resolution, 0.01);
    assert!(file.risk.is_none());
    assert!(!file.grid_offset);
    assert!(file.beam_pooling.is_none() && file.interpolate_beams.is_none());
    assert!(file.unscented.is_none() && file.seeds.is_none() && file.methods.is_none());
    assert_eq!(file.robot.base_link, "base_link");
    assert_eq!(file.robot.sensor_link, "laser");
    assert_eq!((file.robot.xyz, file.robot.rpy), ([0.0; 3], [0.0; 3]));
    assert_eq!(
        (file.world_from_scene.xyz, file.world_from_scene.rpy),
        ([0.0; 3], [0.0; 3])
    );
    assert!(file.viewpoints.is_empty() && file.sweeps.is_empty());
    assert_eq!(
        file.registration_belief,
        crate::experiment::run::registration_belief::BeliefSettings {
            threshold: 0.5,
            draws: 32
        }
    );
    assert_eq!(file.sensor.vertical_fov_deg, 0.0);
    assert_eq!(file.sensor.vertical_step_deg, None);
    // The scaled sigma-point set's defaults: β = 2, κ = 0.
    let scaled: super::file::ScaledSetSpec = toml::from_str("alpha = 0.5").unwrap();
    assert_eq!((scaled.beta, scaled.kappa), (2.0, 0.0));
}

#[test]
fn seeds_read_a_list_or_an_inclusive_range() {
    #[derive(Deserialize)]
    struct File {
        seeds: SeedsSpec,
    }
    let read = |text: &str| toml::from_str::<File>(text).unwrap().seeds.seeds(1000);
    assert_eq!(read("seeds = [3, 1]"), Ok(vec![3, 1]));
    assert_eq!(read("seeds = \"1..40\""), Ok((1..=40).collect()));
    assert_eq!(read("seeds = \"1..=40\"").unwrap().len(), 40);
    assert_eq!(read("seeds = \" 7 .. 7 \""), Ok(vec![7]));
    for bad in ["\"1-40\"", "\"a..b\"", "\"1..\"", "\"-1..3\""] {
        let error = read(&format!("seeds = {bad}")).unwrap_err();
        assert!(error.contains("inclusive range"), "{bad}: {error}");
    }
    assert!(read("seeds = \"5..4\"").unwrap_err().contains("empty"));
    // An absurd range is refused before a seed is made.
    let error = read("seeds = \"0..18446744073709551615\"").unwrap_err();
    assert!(error.contains("18446744073709551616 seeds"), "{error}");
    assert!(read("seeds = \"1..1000\"").is_ok());
    assert!(read("seeds = \"1..1001\"").is_err());
}

#[test]
fn a_setting_of_the_wrong_type_says_what_to_write() {
    #[derive(Deserialize)]
    #[allow(dead_code)]
    struct File {
        seeds: Option<SeedsSpec>,
        beam_pooling: Option<PoolingSpec>,
        interpolate_beams: Option<SwitchSpec>,
        risk: Option<RiskSpec>,
    }
    for (text, says) in [
        (
            "seeds = -3",
            "seeds: a list of whole numbers (seeds = [1, 2, 3]) or an inclusive range",
        ),
        ("seeds = [1, -2]", "seeds: a list of whole numbers"),
        (
            "beam_pooling = 3",
            "beam_pooling: true, false, \"windows\", \"faces\" or \"off\"",
        ),
        (
            "interpolate_beams = 1",
            "interpolate_beams: true or \"on\", false or \"off\"",
        ),
        (
            "risk = [0.1]",
            "risk: a probability between 1e-9 and 0.5, or \"off\"",
        ),
    ] {
        let error = toml::from_str::<File>(text).err().unwrap().to_string();
        assert!(error.contains(says), "{text}: {error}");
        assert!(!error.contains("untagged"), "{text}: {error}");
    }
}

#[test]
fn the_reference_is_a_listed_method_and_defaults_to_the_ray_update() {
    use crate::mapping::Method::*;
    let own = |methods: &[crate::mapping::Method]| -> Vec<RunMethod> {
        methods.iter().map(|m| RunMethod::Own(*m)).collect()
    };
    assert_eq!(
        reference_method(None, &own(&[Blind, Unscented, RayUpdate])),
        Ok(RunMethod::Own(RayUpdate))
    );
    assert_eq!(
        reference_method(None, &own(&[Unscented, Blind])),
        Ok(RunMethod::Own(Unscented))
    );
    assert_eq!(
        reference_method(Some("blind"), &own(&[Unscented, Blind])),
        Ok(RunMethod::Own(Blind))
    );
    let error = reference_method(Some("jacobian"), &own(&[Unscented, Blind])).unwrap_err();
    assert!(
        error.contains("not one of `methods` or the [[mapper]] tables (unscented, blind)"),
        "{error}"
    );
}

#[test]
fn an_experiment_file_with_a_seed_range_and_a_reference_loads() {
    let dir = tempfile::tempdir().unwrap();
    let text = crate::experiment::portable_quickstart().replace(
        "seeds = [1, 2, 3]",
        "seeds = \"11..14\"\nreference = \"blind\"",
    );
    let path = dir.path().join("e.toml");
    std::fs::write(&path, &text).unwrap();
    let experiment = Experiment::load(&path).unwrap();
    assert_eq!(experiment.seeds, vec![11, 12, 13, 14]);
    assert_eq!(
        experiment.reference,
        RunMethod::Own(crate::mapping::Method::Blind)
    );
    std::fs::write(&path, text.replace("\"11..14\"", "\"11..x\"")).unwrap();
    let error = Experiment::load(&path).err().unwrap().to_string();
    assert!(
        error.contains("e.toml") && error.contains("seeds = \"11..x\""),
        "{error}"
    );
}

/// A depth camera's error (`[range] along = "depth"`) is refused on a laser
/// scanner's raster and on a pinhole whose beams reach more than 85° off
/// its axis, naming the experiment file; the depth camera experiment takes it.
#[test]
fn a_depth_cameras_error_needs_a_depth_camera() {
    let shipped = |name: &str| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("experiments")
            .join(name)
    };
    let along = |axis: &str| {
        (
            "profile.range.along".to_string(),
            SweepValue::Text(axis.into()),
        )
    };
    let camera = Experiment::load_cell(&shipped("depth_camera.toml"), &[along("depth")]).unwrap();
    assert_eq!(
        camera.profile.range.along,
        crate::uncertainty::RangeAxis::Depth
    );
    let error = |name: &str, cell: &[(String, SweepValue)]| match Experiment::load_cell(
        &shipped(name),
        cell,
    ) {
        Ok(_) => panic!("{name} loads with {cell:?}"),
        Err(e) => e.to_string(),
    };
    let profile = (
        "experiment.error_profile".to_string(),
        SweepValue::Text("profiles/depth_camera.toml".into()),
    );
    let laser = error("quickstart.toml", &[profile]);
    assert!(laser.contains("quickstart.toml"), "{laser}");
    assert!(
        laser.contains("along = \"depth\") and [sensor] is a laser scanner's raster"),
        "{laser}"
    );
    let wide = [
        along("depth"),
        (
            "experiment.sensor.horizontal_fov_deg".to_string(),
            SweepValue::Number(175.0),
        ),
    ];
    let message = error("depth_camera.toml", &wide);
    assert!(message.contains("deg off the optical axis"), "{message}");
    assert!(Experiment::load_cell(&shipped("depth_camera.toml"), &[along("ray")]).is_ok());
}
