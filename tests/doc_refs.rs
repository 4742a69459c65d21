//! The codebase explains itself: every `§` the code, the tests, the
//! experiments and the README cite is a heading of docs/math.md, every doc
//! file they name exists, and the top-level modules import each other without
//! a cycle (docs/architecture.md).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const SECTION: char = '\u{a7}';

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files(&path, out);
        } else if matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("rs" | "toml" | "md" | "sh" | "cpp")
        ) {
            out.push(path);
        }
    }
}

/// The files whose references must resolve.
fn citing_files() -> Vec<PathBuf> {
    let root = Path::new(ROOT);
    let mut out = vec![root.join("README.md"), root.join(".ci/run")];
    for dir in [
        "src",
        "tests",
        "benches",
        "experiments",
        "scenes",
        ".ci",
        "docs",
    ] {
        files(&root.join(dir), &mut out);
    }
    // This file names dangling references on purpose, to test the parsers.
    out.retain(|p| !p.ends_with("tests/doc_refs.rs"));
    out
}

/// The section numbers of `text`'s `§` references: `§5.4` gives "5.4";
/// `§4.3–4.4` and `§1–3` give both ends.
fn section_refs(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let chars: Vec<char> = text.chars().collect();
    let number = |mut i: usize| -> (String, usize) {
        let mut s = String::new();
        while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
            s.push(chars[i]);
            i += 1;
        }
        (s.trim_end_matches('.').to_string(), i)
    };
    for (i, c) in chars.iter().enumerate() {
        if *c != SECTION {
            continue;
        }
        let mut j = i + 1;
        while j < chars.len() && chars[j] == ' ' {
            j += 1;
        }
        let (first, end) = number(j);
        if first.is_empty() {
            continue;
        }
        out.push(first);
        if end < chars.len() && (chars[end] == '\u{2013}' || chars[end] == '-') {
            let (second, _) = number(end + 1);
            if !second.is_empty() {
                out.push(second);
            }
        }
    }
    out
}

/// The headings of docs/math.md that carry a section number.
fn math_sections() -> BTreeSet<String> {
    let math = std::fs::read_to_string(Path::new(ROOT).join("docs/math.md")).unwrap();
    math.lines()
        .filter(|l| l.starts_with('#'))
        .flat_map(section_refs)
        .collect()
}

#[test]
fn every_cited_section_is_a_heading_of_docs_math() {
    let sections = math_sections();
    assert!(
        sections.contains("5.4") && sections.len() > 30,
        "{sections:?}"
    );
    let mut dangling = Vec::new();
    for path in citing_files() {
        let text = std::fs::read_to_string(&path).unwrap();
        for (line_no, line) in text.lines().enumerate() {
            for r in section_refs(line) {
                if !sections.contains(&r) {
                    dangling.push(format!("{}:{}: §{r}", path.display(), line_no + 1));
                }
            }
        }
    }
    assert!(
        dangling.is_empty(),
        "references to no heading of docs/math.md:\n{}",
        dangling.join("\n")
    );
}

/// Words of `text` that name a Markdown file (`docs/math.md`, `MATH.md`).
fn doc_names(text: &str) -> Vec<String> {
    text.split(|c: char| !(c.is_ascii_alphanumeric() || matches!(c, '/' | '_' | '-' | '.')))
        .map(|w| w.trim_end_matches('.'))
        .filter(|w| w.ends_with(".md") && w.len() > 3)
        .map(str::to_string)
        .collect()
}

#[test]
fn every_named_doc_file_exists() {
    let root = Path::new(ROOT);
    let mut missing = Vec::new();
    for path in citing_files() {
        let text = std::fs::read_to_string(&path).unwrap();
        for (line_no, line) in text.lines().enumerate() {
            for name in doc_names(line) {
                let found = root.join(&name).is_file()
                    || root.join("docs").join(&name).is_file()
                    || path.parent().is_some_and(|d| d.join(&name).is_file());
                if !found {
                    missing.push(format!("{}:{}: {name}", path.display(), line_no + 1));
                }
            }
        }
    }
    assert!(
        missing.is_empty(),
        "doc files named but not in the repository:\n{}",
        missing.join("\n")
    );
}

/// The top-level modules of the crate a piece of library code names: every
/// `crate::` path, inline or in a `use` (grouped ones too:
/// `use crate::{geometry::Pose, sim::{scan, sensor}}` names `geometry` and
/// `sim`), comments left out.
fn crate_paths(text: &str) -> BTreeSet<String> {
    let code: String = text
        .lines()
        .map(|line| match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut out = BTreeSet::new();
    let mut rest = code.as_str();
    while let Some(at) = rest.find("crate::") {
        let before = rest[..at].chars().next_back();
        rest = &rest[at + "crate::".len()..];
        if before.is_some_and(|c| ident(c) || c == ':') {
            continue;
        }
        let after = rest.trim_start();
        if let Some(group) = after.strip_prefix('{') {
            // The first segment of each item at the group's top level.
            let (mut depth, mut item) = (0usize, String::new());
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        out.extend(first_segment(&item));
                        item.clear();
                        continue;
                    }
                    _ => {}
                }
                if depth == 0 {
                    item.push(c);
                }
            }
            out.extend(first_segment(&item));
        } else {
            out.extend(first_segment(after));
        }
    }
    out
}

/// The identifier a path starts with (`sim` of `sim::scan::Scan`).
fn first_segment(path: &str) -> Option<String> {
    let name: String = path
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    (!name.is_empty() && name != "self").then_some(name)
}

/// The top-level modules of src/ (without `lib` and `main`).
fn top_level_modules() -> Vec<String> {
    let src = Path::new(ROOT).join("src");
    std::fs::read_dir(&src)
        .unwrap()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let name = name.trim_end_matches(".rs").to_string();
            (name != "lib" && name != "main").then_some(name)
        })
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect()
}

/// The top-level modules each top-level module of src/ names, outside test
/// code (`#[cfg(test)]` onward, `tests.rs`, `tests/` folders).
fn module_imports() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(ROOT).join("src");
    let modules = top_level_modules();
    let mut graph = BTreeMap::new();
    for module in &modules {
        let mut paths = Vec::new();
        files(&src.join(module), &mut paths);
        let file = src.join(format!("{module}.rs"));
        if file.is_file() {
            paths.push(file);
        }
        let mut uses = BTreeSet::new();
        for path in paths {
            let text = std::fs::read_to_string(&path).unwrap();
            // Test code may reach anywhere; the library may not.
            let library = text.split("#[cfg(test)]").next().unwrap_or("");
            if path.file_name().is_some_and(|n| n == "tests.rs")
                || path.components().any(|c| c.as_os_str() == "tests")
            {
                continue;
            }
            uses.extend(
                crate_paths(library)
                    .into_iter()
                    .filter(|m| m != module && modules.contains(m)),
            );
        }
        graph.insert(module.clone(), uses);
    }
    graph
}

/// The table of docs/architecture.md: each module and what it may import
/// (`- **`sim`** (error, geometry, ...)`; "nothing", "everything above",
/// "everything").
fn allowed_imports(text: &str) -> BTreeMap<String, BTreeSet<String>> {
    let mut table: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut above: Vec<String> = Vec::new();
    for line in text.lines() {
        let Some(rest) = line.strip_prefix("- **`") else {
            continue;
        };
        let Some((module, rest)) = rest.split_once("`** (") else {
            continue;
        };
        let Some((list, _)) = rest.split_once(')') else {
            continue;
        };
        let allowed: BTreeSet<String> = match list.trim() {
            "nothing" | "imports nothing" => BTreeSet::new(),
            "everything above" => above.iter().cloned().collect(),
            "everything" => top_level_modules().into_iter().collect(),
            list => list.split(',').map(|m| m.trim().to_string()).collect(),
        };
        table.insert(module.to_string(), allowed);
        above.push(module.to_string());
    }
    table
}

/// Every import of `graph` that `table` does not allow, as `a -> b`.
fn forbidden_imports(
    graph: &BTreeMap<String, BTreeSet<String>>,
    table: &BTreeMap<String, BTreeSet<String>>,
) -> Vec<String> {
    let mut out = Vec::new();
    for (module, uses) in graph {
        match table.get(module) {
            None => out.push(format!("{module} is not in docs/architecture.md's table")),
            Some(allowed) => out.extend(
                uses.iter()
                    .filter(|u| !allowed.contains(*u))
                    .map(|u| format!("{module} -> {u}")),
            ),
        }
    }
    out
}

#[test]
fn every_import_is_an_arrow_of_the_architecture_table() {
    let text = std::fs::read_to_string(Path::new(ROOT).join("docs/architecture.md")).unwrap();
    let table = allowed_imports(&text);
    assert!(table["mapping"].contains("geometry") && !table["mapping"].contains("sim"));
    let graph = module_imports();
    let forbidden = forbidden_imports(&graph, &table);
    assert!(
        forbidden.is_empty(),
        "imports docs/architecture.md does not allow: {forbidden:?}"
    );
    // The check sees what a substring search would miss: a grouped import,
    // over lines, of a module the table forbids.
    let sneaky = "use crate::{\n    geometry::Pose,\n    sim::{scan::Scan, sensor},\n};\n\
                  fn f() -> crate::eval::Scores { todo!() } // crate::cli in a comment";
    let mut with_sneaky = graph.clone();
    with_sneaky
        .get_mut("mapping")
        .unwrap()
        .extend(crate_paths(sneaky));
    assert_eq!(
        crate_paths(sneaky),
        ["eval", "geometry", "sim"].map(String::from).into()
    );
    assert_eq!(
        forbidden_imports(&with_sneaky, &table),
        ["mapping -> eval", "mapping -> sim"]
    );
}

#[test]
fn top_level_modules_import_each_other_without_a_cycle() {
    let graph = module_imports();
    assert!(graph["mapping"].contains("geometry"), "{graph:?}");
    // Depth-first search for a back edge.
    fn visit<'a>(
        node: &'a str,
        graph: &'a BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<&'a str, u8>,
        path: &mut Vec<&'a str>,
    ) -> Option<Vec<String>> {
        match state.get(node) {
            Some(2) => return None,
            Some(1) => {
                let start = path.iter().position(|n| *n == node).unwrap();
                let mut cycle: Vec<String> = path[start..]
                    .iter()
                    .map(std::string::ToString::to_string)
                    .collect();
                cycle.push(node.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(node, 1);
        path.push(node);
        for next in graph.get(node).into_iter().flatten() {
            if let Some(cycle) = visit(next, graph, state, path) {
                return Some(cycle);
            }
        }
        path.pop();
        state.insert(node, 2);
        None
    }
    let mut state = BTreeMap::new();
    for node in graph.keys() {
        if let Some(cycle) = visit(node, &graph, &mut state, &mut Vec::new()) {
            panic!(
                "import cycle between top-level modules: {}",
                cycle.join(" -> ")
            );
        }
    }
    // What docs/architecture.md promises of the mapper and the scorer.
    for forbidden in ["sim", "eval", "experiment", "cli"] {
        assert!(
            !graph["mapping"].contains(forbidden),
            "mapping imports {forbidden}: the truth must not reach a mapper"
        );
    }
    assert!(!graph["eval"].contains("experiment"), "{graph:?}");
}

#[test]
fn the_reference_parsers_find_what_they_must() {
    let s = SECTION;
    assert_eq!(
        section_refs(&format!("see {s}4.3–4.4 and {s} 1–3, {s}5.4.")),
        ["4.3", "4.4", "1", "3", "5.4"]
    );
    assert_eq!(
        doc_names("(docs/math.md §5.4; the project's MATH.md)."),
        ["docs/math.md", "MATH.md"]
    );
}

#[test]
fn map_building_cannot_name_the_truth() {
    // `build_map` takes a `MapperView` (beam layouts, range model, map
    // settings) and `Scan`s (measurements, believed chain); the truth is
    // `ScanTruth` / `RunTruth`, the scene is `Scene`. The map builder lives
    // in `mapping`, which may not import `sim` (the layering test), and its
    // library code names none of them (docs/architecture.md).
    let mapping = Path::new(ROOT).join("src/mapping");
    let library = |name: &str| {
        let text = std::fs::read_to_string(mapping.join(name)).unwrap();
        text.split("#[cfg(test)]").next().unwrap().to_string()
    };
    assert!(
        library("build.rs").contains("pub fn build_map("),
        "mapping/build.rs builds maps"
    );
    // The truth's types by name (`Method::RegisteredTruth`, a reference the
    // runner builds from the truth, is only a name here).
    for file in ["build.rs", "measured.rs", "method.rs", "scan.rs"] {
        let library = library(file);
        for word in [
            "ScanTruth",
            "RunTruth",
            "BeamTruth",
            "truth::",
            ".truth",
            "SimulatedRun",
            "Scene",
            "experiment.scene",
        ] {
            assert!(
                !library.contains(word),
                "src/mapping/{file} names `{word}`: the truth and the scene must not reach a mapper"
            );
        }
    }
    let scan = library("scan.rs");
    let fields = scan
        .split("pub struct Scan {")
        .nth(1)
        .and_then(|rest| rest.split("\n}").next())
        .expect("mapping/scan.rs defines Scan");
    assert!(!fields.contains("Truth"), "Scan carries the truth:{fields}");
    // One map builder: no other file of the library dispatches on methods
    // to build a map.
    let mut paths = Vec::new();
    files(&Path::new(ROOT).join("src"), &mut paths);
    for path in paths {
        let text = std::fs::read_to_string(&path).unwrap();
        let library = text.split("#[cfg(test)]").next().unwrap();
        let builds = ["RayUpdater::new(", "merge_options()", "take_shared_motion("];
        let test_code = path.file_name().is_some_and(|n| n == "tests.rs")
            || path.components().any(|c| c.as_os_str() == "tests");
        if path.ends_with("src/mapping/build.rs") || test_code {
            continue;
        }
        for call in builds {
            assert!(
                !library.contains(call),
                "{} calls `{call}`: maps are built by mapping::build_map alone",
                path.display()
            );
        }
    }
}
