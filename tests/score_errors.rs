//! `sigmap score --errors`: the cells a map calls wrongly, as CSV, PLY and
//! OctoMap colour tree, against the rates that count them.

mod common;

use common::{sigmap, sigmap_ok};
use sigmap::geometry::Point3;
use sigmap::mapping::octomap_io::read_octree;
use sigmap::mapping::Clamp;
use std::path::Path;

/// A runs.csv row: (column, value) in file order.
type Row = Vec<(String, String)>;

fn path(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// The quickstart's ray-update map scored with `--errors` into `dir` as
/// `errors.csv`, `errors.ply` and `errors.ot`, and its row in `row.csv`.
fn score_with_errors(dir: &Path) -> (String, Vec<u8>, Row) {
    let map = dir.join("map.ot");
    common::quickstart_ray_update_map(&map);
    let (csv, ply, row) = (
        dir.join("errors.csv"),
        dir.join("errors.ply"),
        dir.join("row.csv"),
    );
    let ot = dir.join("errors.ot");
    for (errors, extra) in [
        (&csv, vec!["--csv", row.to_str().unwrap()]),
        (&ply, vec![]),
        (&ot, vec![]),
    ] {
        let args = ["score", &path(&map), "experiments/quickstart.toml", "-q"];
        sigmap_ok(&[&args[..], &["--errors", &path(errors)], &extra[..]].concat());
    }
    let mut reader = csv::Reader::from_path(&row).unwrap();
    let header = reader.headers().unwrap().clone();
    let values = reader.records().next().unwrap().unwrap();
    let row: Row = header
        .iter()
        .map(String::from)
        .zip(values.iter().map(String::from))
        .collect();
    (
        std::fs::read_to_string(&csv).unwrap(),
        std::fs::read(&ply).unwrap(),
        row,
    )
}

/// `score --errors` lists exactly the cells the false-free and
/// false-occupied rates count, with the map's probability on the wrong side
/// of ½; the PLY holds the same cells in the same order, coloured by error,
/// and the `.ot` the same cells, each a finest occupied leaf; another
/// extension is refused before anything is scored.
#[test]
fn score_lists_the_cells_its_rates_count() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, ply, row) = score_with_errors(dir.path());
    let get = |name: &str| -> f64 {
        row.iter()
            .find(|(c, _)| c == name)
            .unwrap()
            .1
            .parse()
            .unwrap()
    };
    let lines: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let count = |error: &str| lines.iter().filter(|l| l[3] == error).count() as f64;
    let (occupied, observable) = (get("occupied_cells"), get("observable_cells"));
    assert!(count("false_free") > 10.0 && count("false_occupied") > 10.0);
    assert_eq!(
        count("false_free"),
        (get("false_free_rate") * occupied).round()
    );
    assert_eq!(
        count("false_occupied"),
        (get("false_occupied_rate") * (observable - occupied)).round()
    );
    assert_eq!(
        count("false_free") + count("false_occupied"),
        lines.len() as f64
    );
    for line in &lines {
        let p: f64 = line[5].parse().unwrap();
        assert!(
            if line[3] == "false_free" {
                p < 0.5
            } else {
                p > 0.5
            },
            "{line:?}"
        );
    }
    // The PLY: a header, then 27 bytes a cell (x, y, z f64, r, g, b).
    let end = ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let header = String::from_utf8_lossy(&ply[..end]);
    assert!(header.contains(&format!("element vertex {}\n", lines.len())));
    assert_eq!(ply.len() - end, 27 * lines.len());
    let first = &ply[end..end + 27];
    let x = f64::from_le_bytes(first[..8].try_into().unwrap());
    assert_eq!(x, lines[0][0].parse::<f64>().unwrap());
    let red = if lines[0][3] == "false_free" {
        [220, 30, 30]
    } else {
        [245, 150, 20]
    };
    assert_eq!(first[24..], red);
    let tree = read_octree(&dir.path().join("errors.ot"), Clamp::OCTOMAP).unwrap();
    let mut leaves: Vec<_> = tree
        .leaves()
        .into_iter()
        .map(|l| (l.key.0, l.depth, l.value.to_bits()))
        .collect();
    leaves.sort_unstable();
    let mut listed: Vec<_> = lines
        .iter()
        .map(|l| {
            let centre = Point3::new(
                l[0].parse().unwrap(),
                l[1].parse().unwrap(),
                l[2].parse().unwrap(),
            );
            (
                tree.key(&centre).unwrap().0,
                16,
                Clamp::OCTOMAP.max.to_bits(),
            )
        })
        .collect();
    listed.sort_unstable();
    assert_eq!(leaves, listed, "the .ot's leaves are the CSV's cells");
    let wrong = dir.path().join("errors.txt");
    let refused = sigmap(&[
        "score",
        &path(&dir.path().join("map.ot")),
        "experiments/quickstart.toml",
        "--errors",
        &path(&wrong),
    ]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("errors.txt") && stderr.contains(".ply"),
        "{stderr}"
    );
    assert!(!wrong.exists());
}

/// The `--errors` PLY opens in an independent reader (Python's `plyfile`,
/// which `.ci/run` installs) with the cells of the CSV.
#[test]
#[ignore = "needs python3 with plyfile (pip install plyfile); .ci/run runs it"]
fn errors_ply_reads_in_an_independent_reader() {
    common::require_plyfile();
    let dir = tempfile::tempdir().unwrap();
    let (csv, _, _) = score_with_errors(dir.path());
    let script = "import sys; from plyfile import PlyData\n\
                  v = PlyData.read(sys.argv[1])['vertex']\n\
                  print(len(v), repr(float(v[0]['z'])), v[0]['red'], v[0]['green'])";
    let ply = dir.path().join("errors.ply");
    let text = common::tool_ok(std::process::Command::new("python3").args([
        "-c",
        script,
        ply.to_str().unwrap(),
    ]));
    let fields: Vec<&str> = text.split_whitespace().collect();
    let first: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    assert_eq!(fields[0].parse::<usize>().unwrap(), csv.lines().count() - 1);
    assert_eq!(
        fields[1].parse::<f64>().unwrap(),
        first[2].parse::<f64>().unwrap()
    );
    let (red, green) = if first[3] == "false_free" {
        ("220", "30")
    } else {
        ("245", "150")
    };
    assert_eq!((fields[2], fields[3]), (red, green));
}

/// `--errors` never replaces a file it did not write: a file of the user's
/// at its path (CSV or PLY), or the `--csv` file of the same call, is
/// refused (exit 2) and left as it was; a list it wrote is replaced.
#[test]
fn errors_never_replaces_a_file_it_did_not_write() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    score_with_errors(d);
    let map = path(&d.join("map.ot"));
    let score = |extra: &[&str]| {
        let args = ["score", &map, "experiments/quickstart.toml", "-q"];
        sigmap(&[&args[..], extra].concat())
    };
    for name in ["mine.csv", "mine.ply"] {
        let mine = d.join(name);
        std::fs::write(&mine, "my own points\n").unwrap();
        let refused = score(&["--errors", &path(&mine)]);
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert_eq!(refused.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains(name) && stderr.contains("not a list"),
            "{stderr}"
        );
        assert_eq!(std::fs::read_to_string(&mine).unwrap(), "my own points\n");
    }
    // The map itself named as the `.ot` list: an OctoMap file sigmap score
    // did not write, left as it is.
    let before = std::fs::read(&map).unwrap();
    let refused = score(&["--errors", &map]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("not a list"), "{stderr}");
    assert_eq!(std::fs::read(&map).unwrap(), before);
    let both = path(&d.join("both.csv"));
    let refused = score(&["--errors", &both, "--csv", &both]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(!d.join("both.csv").exists());
    // The lists written before are replaced by the same lists.
    let before = ["errors.ply", "errors.ot"].map(|list| std::fs::read(d.join(list)).unwrap());
    for list in ["errors.csv", "errors.ply", "errors.ot"] {
        assert!(score(&["--errors", &path(&d.join(list))]).status.success());
    }
    let after = ["errors.ply", "errors.ot"].map(|list| std::fs::read(d.join(list)).unwrap());
    assert_eq!(after, before);
}
