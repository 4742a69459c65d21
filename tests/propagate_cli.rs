//! End-to-end runs of `sigmap propagate`: the JSON contract, the sweep files,
//! and chain files written by `sigmap simulate`.

use std::process::Output;

mod common;

use common::{sigmap, sigmap_ok, simulate_quickstart};

const CHAIN: &str = r#"
[[transform]]
name = "world_from_scene"
xyz = [0.1, 0.0, 0.2]
rpy = [0.0, 0.0, 0.3]
inverse = true
sigma = [0.001, 0.001, 0.001, 0.002, 0.002, 0.002]
[[transform]]
name = "world_from_robot"
xyz = [0.6, 0.1, 0.5]
rpy = [3.0, 0.2, -1.1]
sigma = [0.0005, 0.0005, 0.0005, 0.003, 0.003, 0.003]
[[transform]]
name = "robot_from_camera"
xyz = [0.0, 0.07, 0.045]
rpy = [0.0, 0.0, -1.57]
sigma = [0.001, 0.001, 0.001, 0.002, 0.002, 0.002]
[point]
xyz = [0.0, 0.1, 1.2]
sigma = [0.0005, 0.0005, 0.0005]
"#;

fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("valid JSON")
}

fn matrix(v: &serde_json::Value) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| v[i][j].as_f64().unwrap()))
}

#[test]
fn json_has_every_method_and_agrees_with_monte_carlo() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chain.toml");
    std::fs::write(&path, CHAIN).unwrap();
    let v = json(&sigmap(&[
        "propagate",
        path.to_str().unwrap(),
        "--samples",
        "20000",
        "--seed",
        "3",
        "--json",
    ]));
    assert_eq!(v["sigma_points"], 42);
    let methods = &v["methods"];
    for m in ["blind", "jacobian", "unscented", "monte_carlo"] {
        let r = &methods[m];
        assert_eq!(r["mean"].as_array().unwrap().len(), 3, "{m}");
        let micros = r["micros"].as_f64().unwrap();
        assert!(micros.is_finite() && micros > 0.0, "{m}: {micros} µs");
        let c = matrix(&r["covariance"]);
        for (i, row) in c.iter().enumerate() {
            for (j, value) in row.iter().enumerate() {
                assert_eq!(*value, c[j][i], "{m} covariance must be symmetric");
            }
        }
    }
    // Variances of Jacobian and UT within 5 Monte Carlo standard errors
    // (relative SE √(2/(N−1)) = 1% at N = 20 000); blind far below.
    let mc = matrix(&methods["monte_carlo"]["covariance"]);
    let se = (2.0f64 / 19_999.0).sqrt();
    for m in ["jacobian", "unscented"] {
        let c = matrix(&methods[m]["covariance"]);
        for i in 0..3 {
            assert!(
                (c[i][i] / mc[i][i] - 1.0).abs() < 5.0 * se,
                "{m} variance {i}: {} vs {}",
                c[i][i],
                mc[i][i]
            );
        }
    }
    let blind = matrix(&methods["blind"]["covariance"]);
    assert!(
        blind[0][0] < 0.1 * mc[0][0],
        "blind ignores the pose errors"
    );
    // --point replaces the mean; same seed, same Monte Carlo answer.
    let a = json(&sigmap(&[
        "propagate",
        path.to_str().unwrap(),
        "--point",
        "0.1,-0.2,0.9",
        "--json",
    ]));
    let b = json(&sigmap(&[
        "propagate",
        path.to_str().unwrap(),
        "--point",
        "0.1,-0.2,0.9",
        "--json",
    ]));
    assert_eq!(
        a["methods"]["monte_carlo"]["covariance"],
        b["methods"]["monte_carlo"]["covariance"]
    );
    assert_ne!(
        a["methods"]["jacobian"]["mean"],
        v["methods"]["jacobian"]["mean"]
    );
}

#[test]
fn sweep_writes_csv_and_svg() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chain.toml");
    std::fs::write(&path, CHAIN).unwrap();
    let out_dir = dir.path().join("sweep");
    sigmap_ok(&[
        "propagate",
        path.to_str().unwrap(),
        "--sweep",
        "--sweep-points",
        "5",
        "--samples",
        "4000",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let mut reader = csv::Reader::from_path(out_dir.join("sweep.csv")).unwrap();
    let rows: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
    assert_eq!(rows.len(), 5 * 3);
    assert_eq!(&rows[0][0], "0.001");
    assert_eq!(&rows[rows.len() - 1][0], "0.2");
    // At the smallest sigma the Jacobian is within Monte Carlo noise; blind is not.
    let frob = |method: &str, k: usize| -> f64 {
        rows.iter().filter(|r| &r[1] == method).nth(k).unwrap()[2]
            .parse()
            .unwrap()
    };
    assert!(frob("jacobian", 0) < 0.1);
    assert!(frob("blind", 0) > 0.5);
    let svg = std::fs::read_to_string(out_dir.join("sweep.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("jacobian") && svg.contains("unscented"));
}

#[test]
fn chain_files_from_simulate_propagate() {
    let dir = tempfile::tempdir().unwrap();
    let scans = dir.path().join("scans");
    simulate_quickstart(&scans, &[]);
    let chain = scans.join("vp_001.chain.toml");
    let v = json(&sigmap(&[
        "propagate",
        chain.to_str().unwrap(),
        "--point",
        "0,0,0.5",
        "--json",
        "--samples",
        "2000",
    ]));
    // T_sw is uncertain in the collaborative profile: 42 sigma points (21 x 2).
    assert_eq!(v["sigma_points"], 42);
    let missing = sigmap(&["propagate", chain.to_str().unwrap()]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("--point"));
}

#[test]
fn bad_chain_files_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text, says) in [
        (
            "neg.toml",
            CHAIN.replace(
                "sigma = [0.0005, 0.0005, 0.0005, 0.003",
                "sigma = [0.0005, -0.0005, 0.0005, 0.003",
            ),
            "negative",
        ),
        (
            "short.toml",
            CHAIN.replace(
                "sigma = [0.0005, 0.0005, 0.0005]",
                "sigma = [0.0005, 0.0005]",
            ),
            "needs 3 values",
        ),
        (
            "typo.toml",
            CHAIN.replace("inverse = true", "invert = true"),
            "malformed TOML",
        ),
        // Absurd magnitudes are refused before they become inf or NaN.
        (
            "far.toml",
            CHAIN.replace("xyz = [0.6, 0.1, 0.5]", "xyz = [1e308, 0.1, 0.5]"),
            "'world_from_robot': xyz has 1e308 m, farther than 1e7 m",
        ),
        (
            "far_point.toml",
            CHAIN.replace("xyz = [0.0, 0.1, 1.2]", "xyz = [0.0, 0.1, 2e7]"),
            "[point] xyz has 2e7 m",
        ),
        (
            "wide.toml",
            CHAIN.replace(
                "sigma = [0.001, 0.001, 0.001, 0.002, 0.002, 0.002]\n[point]",
                "sigma = [0.001, 0.001, 0.001, 0.002, 0.6, 0.002]\n[point]",
            ),
            "'robot_from_camera': sigma[4] = 6e-1 exceeds 0.5 rad",
        ),
        (
            "wide_point.toml",
            CHAIN.replace(
                "sigma = [0.0005, 0.0005, 0.0005]",
                "sigma = [0.0005, 1e200, 0.0005]",
            ),
            "[point]: sigma[1] = inf exceeds 1 m",
        ),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let out = sigmap(&["propagate", path.to_str().unwrap(), "--json"]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {stderr}");
        assert!(
            stderr.contains(name) && stderr.contains(says),
            "{name}: {stderr}"
        );
    }
    let out = sigmap(&["propagate", "nope.toml", "--point", "1,2"]);
    assert_eq!(out.status.code(), Some(2));
    let chain = dir.path().join("chain.toml");
    std::fs::write(&chain, CHAIN).unwrap();
    let out = sigmap(&["propagate", chain.to_str().unwrap(), "--point", "0,0,1e8"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--point xyz has 1e8 m"), "{stderr}");
    // An experiment file given where the chain file goes is named as one.
    let quickstart = common::root().join("experiments/quickstart.toml");
    let out = sigmap(&["propagate", quickstart.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(
            "quickstart.toml: is an experiment file; `sigmap propagate` takes a chain file"
        ),
        "{stderr}"
    );
}

#[test]
fn the_scaled_sigma_point_set_is_offered_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chain.toml");
    std::fs::write(&path, CHAIN).unwrap();
    let p = path.to_str().unwrap();
    let propagate = |extra: &[&str]| {
        let mut args = vec![
            "propagate",
            p,
            "--samples",
            "20000",
            "--seed",
            "3",
            "--json",
        ];
        args.extend_from_slice(extra);
        json(&sigmap(&args))
    };
    let unscented = |v: &serde_json::Value| matrix(&v["methods"]["unscented"]["covariance"]);
    let paper = propagate(&[]);
    // α = 1, β = κ = 0 is the paper's set plus a centre point of weight 0.
    let same = propagate(&["--alpha", "1", "--beta", "0"]);
    assert_eq!(same["sigma_points"], 43);
    assert_eq!(unscented(&same), unscented(&paper));
    // α = 0.5, β = 2: another set, still within 5 Monte Carlo standard
    // errors of the reference on this mildly nonlinear chain.
    let narrow = propagate(&["--alpha", "0.5"]);
    assert_ne!(unscented(&narrow), unscented(&paper));
    let mc = matrix(&narrow["methods"]["monte_carlo"]["covariance"]);
    let se = (2.0f64 / 19_999.0).sqrt();
    for (i, (ut_row, mc_row)) in unscented(&narrow).iter().zip(&mc).enumerate() {
        let ratio = ut_row[i] / mc_row[i];
        assert!(
            (ratio - 1.0).abs() < 5.0 * se,
            "variance {i}: ratio {ratio}"
        );
    }
    // Out of its bounds, or β without α: exit 2.
    for bad in [
        &["--alpha", "0"][..],
        &["--alpha", "0.5", "--kappa=-1"],
        &["--beta", "1"],
    ] {
        let mut args = vec!["propagate", p];
        args.extend_from_slice(bad);
        let out = sigmap(&args);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
    }
    let out = sigmap(&["propagate", p, "--alpha", "0"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--alpha = 0 must be at least 0.0001"),
        "{stderr}"
    );
}
