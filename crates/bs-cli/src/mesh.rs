//! `brainshift mesh`: from a segmentation (labelmap) to a scene folder — brain mesh, skull
//! cavity and scene.toml — with the quality report printed.

use std::path::PathBuf;
use std::process::ExitCode;

use bs_scene::mesh_scene::{ElementType, MeshParams, RegionSpec, mesh_to_scene};

/// The command's options, as given on the command line.
#[derive(Debug, Clone)]
pub struct MeshOptions {
    /// The labelmap (.nii or .nii.gz).
    pub labels: PathBuf,
    /// Output folder.
    pub out: PathBuf,
    /// `--brain 1,2,3` (None: every non-zero label).
    pub brain: Option<String>,
    /// `--region NAME=LABELS`, repeatable.
    pub regions: Vec<String>,
    /// `--size MM`.
    pub size: f64,
    /// `--element t4|h8`.
    pub element: String,
    /// `--skull-offset MM`.
    pub skull_offset: f64,
    /// `--cavity LABELS`.
    pub cavity: Option<String>,
    /// `--craniotomy`: the scene's craniotomy load active instead of commented.
    pub craniotomy: bool,
}

/// Parses a comma-separated list of label values (`"1,2,3"`).
pub fn parse_labels(option: &str, text: &str) -> Result<Vec<u32>, String> {
    let labels: Result<Vec<u32>, String> = text
        .split(',')
        .map(|s| {
            s.trim().parse::<u32>().map_err(|_| {
                format!(
                    "{option} {text}: '{}' is not a label value; write values like 1,2,3",
                    s.trim()
                )
            })
        })
        .collect();
    let labels = labels?;
    if labels.is_empty() {
        return Err(format!("{option}: no label given; write values like 1,2,3"));
    }
    Ok(labels)
}

/// Parses `NAME=LABELS` (`ventricles=4`, `tumour=5,6`).
pub fn parse_region(text: &str) -> Result<RegionSpec, String> {
    let (name, labels) = text
        .split_once('=')
        .ok_or_else(|| format!("--region {text}: expected NAME=LABELS, e.g. ventricles=4"))?;
    Ok(RegionSpec { name: name.trim().to_string(), labels: parse_labels("--region", labels)? })
}

/// The meshing parameters of the options.
pub fn params(o: &MeshOptions) -> Result<MeshParams, String> {
    let element = ElementType::from_name(&o.element)
        .ok_or_else(|| format!("--element {}: expected t4 or h8", o.element))?;
    Ok(MeshParams {
        brain_labels: o.brain.as_deref().map(|b| parse_labels("--brain", b)).transpose()?,
        regions: o.regions.iter().map(|r| parse_region(r)).collect::<Result<_, _>>()?,
        size: o.size,
        element,
        skull_offset: o.skull_offset,
        cavity_labels: o.cavity.as_deref().map(|c| parse_labels("--cavity", c)).transpose()?,
        ..MeshParams::default()
    })
}

/// Runs the command.
pub fn run(o: &MeshOptions) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let p = params(o)?;
    let done = mesh_to_scene(&o.labels, &o.out, &p, o.craniotomy)?;
    let f = &done.files;
    crate::emit(&format!(
        "{}\nwrote {}, {}, {}, {}, {}\n",
        done.meshed.report,
        f.brain_vtu.display(),
        f.brain_vtk.display(),
        f.brain_inp.display(),
        f.skull.display(),
        f.scene.display()
    ));
    // The last line: what the scene still needs before `check` and `run` accept it.
    if let Some(missing) = &done.missing {
        crate::emit(&format!("{missing}\n"));
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_and_regions_parse_or_name_the_fix() {
        assert_eq!(parse_labels("--brain", "1, 2,3").unwrap(), vec![1, 2, 3]);
        assert!(parse_labels("--brain", "1,x").unwrap_err().contains("'x' is not a label"));
        let r = parse_region("ventricles=4,5").unwrap();
        assert_eq!((r.name.as_str(), r.labels), ("ventricles", vec![4, 5]));
        assert!(parse_region("ventricles").unwrap_err().contains("NAME=LABELS"));
    }
}
