//! `sigmap score --errors`: the scored cells a map calls wrongly, as a CSV
//! table, a coloured point cloud (PLY) to look at beside the map, or an
//! OctoMap `ColorOcTree` (`.ot`) for octovis.

use crate::error::{Error, Result};
use crate::eval::scores::{CellError, WrongCell};
use crate::mapping::octomap_io::{colour_cells_to_ot, OT_HEADER};
use crate::mapping::octree::{Clamp, DEPTH};
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
    /// An OctoMap `ColorOcTree` `.ot`: each cell an occupied leaf, coloured
    /// by its error (octovis shows it as it shows a map).
    ColourTree,
}

impl ErrorsFormat {
    /// The format `path`'s extension names; an error saying which ones
    /// exist otherwise, or when `path` holds a file that is not such a list
    /// (it is never replaced), before anything is scored.
    pub fn of(path: &Path) -> Result<Self> {
        let format = match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("csv") => Self::Csv,
            Some(e) if e.eq_ignore_ascii_case("ply") => Self::Ply,
            Some(e) if e.eq_ignore_ascii_case("ot") => Self::ColourTree,
            _ => {
                return Err(Error::Usage(format!(
                    "--errors {}: name a .csv (a table of the cells), a .ply (a coloured \
                     point cloud) or a .ot (an OctoMap ColorOcTree, for octovis) file",
                    path.display()
                )))
            }
        };
        if path.exists() && !format.wrote(path) {
            return Err(Error::Usage(format!(
                "--errors {}: the file exists and is not a list sigmap score --errors wrote; \
                 it is left as it is: choose another file",
                path.display()
            )));
        }
        Ok(format)
    }

    /// How a file of this format begins.
    fn opening(self) -> String {
        match self {
            Self::Csv => CSV_HEADER.into(),
            Self::Ply => PLY_OPENING.into(),
            Self::ColourTree => format!("{OT_HEADER}\n{OT_COMMENT}"),
        }
    }

    /// Whether the file at `path` begins as this format's lists do.
    fn wrote(self, path: &Path) -> bool {
        use std::io::Read as _;
        let opening = self.opening();
        let mut start = vec![0; opening.len()];
        std::fs::File::open(path)
            .and_then(|mut file| file.read_exact(&mut start))
            .is_ok_and(|()| start == opening.as_bytes())
    }
}

/// The CSV's header line.
const CSV_HEADER: &str = "x,y,z,error,log_odds,probability\n";

/// The PLY's first lines, up to what names it sigmap's.
const PLY_OPENING: &str = "ply\nformat binary_little_endian 1.0\ncomment sigmap score --errors: ";

/// The `.ot` header's comment, after its first line, up to what names it
/// sigmap's (OctoMap's reader skips comments).
const OT_COMMENT: &str = "# sigmap score --errors: ";

/// The colour of a wrong cell in the PLY and the `.ot`: false-free red, false-occupied
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
            let mut text = String::from(CSV_HEADER);
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
                "{PLY_OPENING}centres of the scored cells the map calls wrongly, map frame\n\
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
        ErrorsFormat::ColourTree => {
            let mut coloured: Vec<(u64, [u8; 3])> = cells
                .iter()
                .map(|cell| (cell.key.morton(), colour(cell.error)))
                .collect();
            coloured.sort_unstable_by_key(|&(code, _)| code);
            let comment = format!(
                "{OT_COMMENT}the scored cells the map calls wrongly, map frame\n# red: \
                 false-free (truly occupied, called free); orange: false-occupied (truly free, \
                 called occupied); each an occupied leaf\n"
            );
            colour_cells_to_ot(map.resolution(), &coloured, Clamp::OCTOMAP.max, &comment)
        }
    };
    crate::files::write_file(path, &bytes)
}
