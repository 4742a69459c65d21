//! `sigmap score --errors`: the scored cells a map calls wrongly, as a CSV
//! table or a coloured point cloud (PLY) to look at beside the map.

use crate::error::{Error, Result};
use crate::eval::scores::{CellError, WrongCell};
use crate::mapping::octree::DEPTH;
use crate::mapping::opdf::probability;
use crate::mapping::Octree;
use std::fmt::Write as _;
use std::path::Path;

/// The kinds of file `--errors` writes, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorsFormat {
    /// `x,y,z,error,log_odds,probability`, a row per cell.
    Csv,
    /// Binary little-endian PLY: each cell's centre, coloured by its error.
    Ply,
}

impl ErrorsFormat {
    /// The format `path`'s extension names; an error saying which ones
    /// exist otherwise (before anything is scored).
    pub fn of(path: &Path) -> Result<Self> {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("csv") => Ok(Self::Csv),
            Some(e) if e.eq_ignore_ascii_case("ply") => Ok(Self::Ply),
            _ => Err(Error::Usage(format!(
                "--errors {}: name a .csv (a table of the cells) or a .ply (a coloured point \
                 cloud) file",
                path.display()
            ))),
        }
    }
}

/// The colour of a wrong cell in the PLY: false-free red, false-occupied
/// orange (as in `slice.svg`).
fn colour(error: CellError) -> [u8; 3] {
    match error {
        CellError::FalseFree => [220, 30, 30],
        CellError::FalseOccupied => [245, 150, 20],
    }
}

/// Writes `cells` of `map` (centres in the map frame) to `path` in
/// `format`, staged.
pub fn write_wrong_cells(
    path: &Path,
    format: ErrorsFormat,
    map: &Octree,
    cells: &[WrongCell],
) -> Result<()> {
    let bytes = match format {
        ErrorsFormat::Csv => {
            let mut text = String::from("x,y,z,error,log_odds,probability\n");
            for cell in cells {
                let c = map.center(&cell.key, DEPTH);
                let _ = writeln!(
                    text,
                    "{:?},{:?},{:?},{},{:?},{:?}",
                    c.x,
                    c.y,
                    c.z,
                    cell.error.as_str(),
                    cell.log_odds,
                    probability(f64::from(cell.log_odds))
                );
            }
            text.into_bytes()
        }
        ErrorsFormat::Ply => {
            let header = format!(
                "ply\nformat binary_little_endian 1.0\n\
                 comment sigmap score --errors: centres of the scored cells the map calls \
                 wrongly, map frame\n\
                 comment red: false-free (truly occupied, called free); orange: \
                 false-occupied (truly free, called occupied)\n\
                 comment resolution {:?}\nelement vertex {}\nproperty double x\n\
                 property double y\nproperty double z\nproperty uchar red\n\
                 property uchar green\nproperty uchar blue\nend_header\n",
                map.resolution(),
                cells.len()
            );
            let mut bytes = header.into_bytes();
            for cell in cells {
                let c = map.center(&cell.key, DEPTH);
                for v in [c.x, c.y, c.z] {
                    bytes.extend_from_slice(&v.to_le_bytes());
                }
                bytes.extend_from_slice(&colour(cell.error));
            }
            bytes
        }
    };
    crate::files::write_file(path, &bytes)
}
