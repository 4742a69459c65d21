//! The command line's value parsers: each flag's text to its value, with a
//! one-line error that says what to give.

use crate::error::{Error, Result};

/// `--shard i/n`: shard i of n, 1 ≤ i ≤ n.
pub(super) fn parse_shard(text: &str) -> std::result::Result<(usize, usize), String> {
    let (i, n) = text
        .split_once('/')
        .ok_or("expected i/n, for example 2/4")?;
    let (i, n): (usize, usize) = (
        i.trim()
            .parse()
            .map_err(|_| format!("'{i}' is not a shard number"))?,
        n.trim()
            .parse()
            .map_err(|_| format!("'{n}' is not a shard count"))?,
    );
    if n == 0 || i == 0 || i > n {
        return Err(format!("shard {i}/{n} is out of range: use 1 <= i <= n"));
    }
    Ok((i, n))
}

/// `--method`: one of the method names, listed in `--help`.
pub(super) fn method_parser() -> impl clap::builder::TypedValueParser<Value = crate::mapping::Method>
{
    use clap::builder::TypedValueParser as _;
    let names = crate::mapping::Method::ALL.map(crate::mapping::Method::as_str);
    clap::builder::PossibleValuesParser::new(names).try_map(|name| name.parse())
}

/// `--risk`: a level, or `off` (`None`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RiskArg(pub(crate) Option<f64>);

pub(super) fn risk_parser(text: &str) -> std::result::Result<RiskArg, String> {
    if text == "off" {
        return Ok(RiskArg(None));
    }
    match text.parse::<f64>() {
        Ok(level) => Ok(RiskArg(Some(level))),
        Err(_) => Err(format!("'{text}': use a probability up to 0.5, or off")),
    }
}

/// `--beam-pooling`: off, faces or windows, listed in `--help`.
pub(super) fn pooling_parser(
) -> impl clap::builder::TypedValueParser<Value = crate::mapping::pooling::Pooling> {
    use clap::builder::TypedValueParser as _;
    clap::builder::PossibleValuesParser::new(["off", "faces", "windows"]).try_map(|name| {
        crate::mapping::pooling::Pooling::from_name(&name)
            .ok_or_else(|| format!("'{name}': use faces, windows or off"))
    })
}

/// `N` comma-separated finite numbers; `expected` says what they are.
fn finite_numbers<const N: usize>(
    text: &str,
    expected: &str,
) -> std::result::Result<[f64; N], String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|e| format!("'{v}': {e}")))
        .collect::<std::result::Result<_, _>>()?;
    match <[f64; N]>::try_from(values.as_slice()) {
        Ok(numbers) if numbers.iter().all(|v| v.is_finite()) => Ok(numbers),
        _ => Err(format!("expected {expected}")),
    }
}

/// `--scene-pose x,y,z,roll,pitch,yaw` (m, rad).
pub(super) fn parse_pose(text: &str) -> std::result::Result<[f64; 6], String> {
    finite_numbers(text, "six finite numbers x,y,z,roll,pitch,yaw (m, rad)")
}

/// `--intrinsics fx,fy,cx,cy` (pixels).
pub(super) fn parse_intrinsics(text: &str) -> std::result::Result<[f64; 4], String> {
    let expected = "four finite numbers fx,fy,cx,cy (pixels), nonzero focal lengths";
    match finite_numbers::<4>(text, expected)? {
        [0.0, ..] | [_, 0.0, ..] => Err(format!("expected {expected}")),
        k => Ok(k),
    }
}

/// `--point x,y,z` (m).
pub(super) fn parse_point(text: &str) -> std::result::Result<[f64; 3], String> {
    finite_numbers(text, "three finite numbers x,y,z")
}

/// `--tasks`: between 1 and [`crate::experiment::study::cluster::MAX_TASKS`].
pub(super) fn parse_tasks(text: &str) -> std::result::Result<usize, String> {
    let max = crate::experiment::study::cluster::MAX_TASKS;
    match text.parse::<usize>() {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        _ => Err(format!(
            "{text}: a submission has between 1 and {max} tasks"
        )),
    }
}

/// A `--resolution` argument, checked against [`RESOLUTIONS`](crate::mapping::octree::RESOLUTIONS).
pub(crate) fn resolution_arg(resolution: f64) -> Result<f64> {
    if crate::mapping::octree::RESOLUTIONS.contains(&resolution) {
        Ok(resolution)
    } else {
        Err(Error::Usage(
            "--resolution must be between 0.001 and 1 m".into(),
        ))
    }
}
