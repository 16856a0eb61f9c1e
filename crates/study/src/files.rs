//! Where a study folder keeps its renders. The render source writes them here and a render farm
//! fills the same files from separate tasks, so both take the names from this one place: a
//! study run on a folder the farm filled reuses every file instead of rendering it again.
use std::fmt;
use std::path::{Path, PathBuf};

/// One render of a study: the stream pair of seed `index` with `spp` samples per stream, or the
/// PT image with `2 × spp` samples it is compared with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Cell {
    pub kind: CellKind,
    /// Samples per stream (the PT(2n) image has twice as many).
    pub spp: u32,
    /// Seed index within the study: the streams use `first_seed + index`.
    pub index: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CellKind {
    Streams,
    Pt2n,
}

impl CellKind {
    pub fn name(self) -> &'static str {
        match self {
            CellKind::Streams => "streams",
            CellKind::Pt2n => "pt2n",
        }
    }
}

/// The folder of the renders with `n` spp per stream.
pub fn spp_dir(study: &Path, n: u32) -> PathBuf {
    study.join(format!("spp{n:05}"))
}

/// The render file of `cell` in the study folder `study`.
pub fn cell_file(study: &Path, cell: Cell) -> PathBuf {
    let suffix = match cell.kind {
        CellKind::Streams => "streams.exr",
        CellKind::Pt2n => "pt2n.exr",
    };
    spp_dir(study, cell.spp).join(format!("seed-{:03}.{suffix}", cell.index))
}

/// The sidecar with a finished render's seconds; written after the render, so a render without
/// it is not finished.
pub fn timing_file(render: &Path) -> PathBuf {
    render.with_extension("seconds")
}

/// Every cell of a study, in the order the study asks for them: by spp, then seed, the streams
/// before their PT(2n) image.
pub fn cells(spps: &[u32], seeds: u32) -> Vec<Cell> {
    let mut out = Vec::new();
    for &spp in spps {
        for index in 0..seeds {
            for kind in [CellKind::Streams, CellKind::Pt2n] {
                out.push(Cell { kind, spp, index });
            }
        }
    }
    out
}

/// `streams:32:3` (kind, spp per stream, seed index), as `study --cell` takes it.
impl fmt::Display for Cell {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}", self.kind.name(), self.spp, self.index)
    }
}

impl std::str::FromStr for Cell {
    type Err = String;

    fn from_str(s: &str) -> Result<Cell, String> {
        let bad = || format!("{s:?}: expected KIND:SPP:SEED_INDEX with KIND streams or pt2n, e.g. streams:32:0");
        let mut it = s.split(':');
        let (Some(kind), Some(spp), Some(index), None) = (it.next(), it.next(), it.next(), it.next()) else { return Err(bad()) };
        let kind = match kind {
            "streams" => CellKind::Streams,
            "pt2n" => CellKind::Pt2n,
            _ => return Err(bad()),
        };
        let (Ok(spp), Ok(index)) = (spp.parse(), index.parse()) else { return Err(bad()) };
        Ok(Cell { kind, spp, index })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_name_their_files_and_parse_back() {
        let all = cells(&[8, 16], 2);
        assert_eq!(all.len(), 8);
        assert_eq!(all[1], Cell { kind: CellKind::Pt2n, spp: 8, index: 0 });
        let c = Cell { kind: CellKind::Pt2n, spp: 16, index: 1 };
        assert_eq!(cell_file(Path::new("s"), c), Path::new("s/spp00016/seed-001.pt2n.exr"));
        assert_eq!(timing_file(&cell_file(Path::new("s"), c)), Path::new("s/spp00016/seed-001.pt2n.seconds"));
        assert_eq!(c.to_string().parse::<Cell>(), Ok(c));
        for bad in ["", "streams:8", "ref:8:0", "streams:x:0", "streams:8:0:1", "pt2n:-1:0"] {
            assert!(bad.parse::<Cell>().is_err(), "{bad}");
        }
    }
}
