//! The claims' figures beside a committed report: `study all --results FILE` copies every
//! figure a claim names ([`super::Claim::figures`]) from the studies' output folders into
//! `FILE`'s folder `<stem>/<study>/` (for `docs/results/reproduction.md`:
//! `docs/results/reproduction/<study>/`), reduced to half their width and height and to a
//! palette of [`COLOURS`] colours (NeuQuant), so that the report opens with its figures
//! from a clone, offline, and the repository holds one compact set rather than every PNG
//! of every study. Figures of a study that a claim no
//! longer names are removed from its folder; other files are left alone.

use crate::file_error::{FileError, FileOp};
use crate::study::all::AllRun;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The copies are this many times smaller in width and in height.
pub const REDUCTION: u32 = 2;

/// Colours of the copies' palette.
pub const COLOURS: usize = 64;

/// Why a figure could not be copied.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// A PNG that could not be decoded.
    #[error("{path}: {source}")]
    Image {
        /// The figure.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
    /// A PNG that could not be encoded.
    #[error("{path}: {source}")]
    Encode {
        /// The copy.
        path: PathBuf,
        /// Why.
        #[source]
        source: png::EncodingError,
    },
}

/// What [`copy_claim_figures`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Copied {
    /// Figures written.
    pub written: usize,
    /// Their size, bytes.
    pub bytes: u64,
    /// `study/file` of each figure a claim names that its study did not write.
    pub missing: Vec<String>,
}

/// The folder beside the report `results` that holds its figures (`<stem>/`), and its name
/// as the report's links use it.
pub fn folder_of(results: &Path) -> (PathBuf, String) {
    let stem = results.file_stem().map_or_else(
        || "figures".to_string(),
        |s| s.to_string_lossy().into_owned(),
    );
    (results.with_file_name(&stem), stem)
}

/// Copies the claims' figures of `all` into `dest/<study>/`, reduced (module docs).
pub fn copy_claim_figures(all: &AllRun, dest: &Path) -> Result<Copied, FigureError> {
    let mut copied = Copied::default();
    for run in &all.runs {
        let Ok(claims) = &run.claims else { continue };
        let wanted: BTreeSet<&str> = claims
            .claims
            .iter()
            .flat_map(|c| c.figures.iter().map(String::as_str))
            .collect();
        let to = dest.join(run.entry.name);
        std::fs::create_dir_all(&to)
            .map_err(|source| FileError::new(FileOp::Creating, to.clone(), source))?;
        remove_stale(&to, &wanted)?;
        for file in wanted {
            let from = run.dir.join(file);
            if !from.is_file() {
                copied.missing.push(format!("{}/{file}", run.entry.name));
                continue;
            }
            let target = to.join(file);
            copied.bytes += reduce(&from, &target)?;
            copied.written += 1;
        }
    }
    Ok(copied)
}

/// Removes the PNG files of `dir` that are not `wanted`.
fn remove_stale(dir: &Path, wanted: &BTreeSet<&str>) -> Result<(), FileError> {
    let entries =
        std::fs::read_dir(dir).map_err(|source| FileError::new(FileOp::Reading, dir, source))?;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".png") && !wanted.contains(name.as_str()) {
            let path = entry.path();
            std::fs::remove_file(&path)
                .map_err(|source| FileError::new(FileOp::Access, path, source))?;
        }
    }
    Ok(())
}

/// Writes `from` reduced [`REDUCTION`] times into `to`; returns the bytes written.
fn reduce(from: &Path, to: &Path) -> Result<u64, FigureError> {
    let img = image::open(from).map_err(|source| FigureError::Image {
        path: from.to_path_buf(),
        source,
    })?;
    let small = img.resize(
        (img.width() / REDUCTION).max(1),
        (img.height() / REDUCTION).max(1),
        image::imageops::FilterType::Triangle,
    );
    let rgba = small.to_rgba8();
    let quant = color_quant::NeuQuant::new(10, COLOURS, rgba.as_raw());
    let indices: Vec<u8> = rgba
        .as_raw()
        .chunks_exact(4)
        .map(|p| quant.index_of(p) as u8)
        .collect();
    let palette: Vec<u8> = quant
        .color_map_rgba()
        .chunks_exact(4)
        .flat_map(|c| [c[0], c[1], c[2]])
        .collect();
    let encode_err = |source| FigureError::Encode {
        path: to.to_path_buf(),
        source,
    };
    let file =
        std::fs::File::create(to).map_err(|source| FileError::new(FileOp::Writing, to, source))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), rgba.width(), rgba.height());
    enc.set_color(png::ColorType::Indexed);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_palette(palette);
    enc.set_compression(png::Compression::Best);
    let mut writer = enc.write_header().map_err(encode_err)?;
    writer.write_image_data(&indices).map_err(encode_err)?;
    writer.finish().map_err(encode_err)?;
    let len = std::fs::metadata(to)
        .map_err(|source| FileError::new(FileOp::Access, to, source))?
        .len();
    Ok(len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_figure_folder_sits_beside_the_report_under_its_stem() {
        let (dir, name) = folder_of(Path::new("docs/results/reproduction.md"));
        assert_eq!(dir, Path::new("docs/results/reproduction"));
        assert_eq!(name, "reproduction");
    }

    #[test]
    fn a_figure_is_halved_and_stale_ones_are_removed_but_other_files_kept() {
        let dir = std::env::temp_dir().join(format!("repro-figures-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let from = dir.join("a.png");
        image::RgbImage::from_fn(40, 20, |x, _| image::Rgb([(x * 6) as u8, 0, 0]))
            .save(&from)
            .unwrap();
        let out = dir.join("out");
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(out.join("old.png"), b"x").unwrap();
        std::fs::write(out.join("notes.txt"), b"x").unwrap();
        let bytes = reduce(&from, &out.join("a.png")).unwrap();
        assert!(bytes > 0);
        let small = image::open(out.join("a.png")).unwrap();
        assert_eq!((small.width(), small.height()), (20, 10));
        remove_stale(&out, &BTreeSet::from(["a.png"])).unwrap();
        assert!(!out.join("old.png").exists());
        assert!(out.join("notes.txt").exists() && out.join("a.png").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
