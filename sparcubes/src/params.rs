//! Conversion parameters, with the defaults used by the CLI and the pipeline.

use crate::error::{Error, Result};
use crate::stages::refine::RefineParams;
use serde::{Deserialize, Serialize};

/// Largest supported resolution. The sparse grid keeps a dense 4-byte index per 8³ brick,
/// about 540 MB at 4096.
pub const MAX_RESOLUTION: u32 = 4096;

/// Parameters of one conversion. `Copy`, so a job config can hand it to every item.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Params {
    /// Cells per axis of the grid (N); the voxel size is 1/N of the unit cube.
    pub resolution: u32,
    /// Empty cells kept between the mesh's bounding box and the grid border, per side.
    /// At least 3: one for the shell, one for the band around it, one for the flood to pass.
    pub margin_cells: u32,
    /// Half-thickness `t` of the shell built around open parts, in voxels. The shell's
    /// surface is the level set `UDF = t`. Just above √3/2 ≈ 0.866 (the farthest any surface
    /// point can be from its nearest grid vertex), so the inside vertices of a sheet form a
    /// 6-connected digital plane (thickness 2t ≥ |n|₁ ≤ √3) and the shell has no pinholes.
    pub shell_half_thickness: f32,
    /// Whether to move active vertices towards the surface (paper step 3). Off by default:
    /// on the dev corpus at 256³ it did not beat plain extraction of the exact distance
    /// (docs/QUALITY.md).
    pub deform: bool,
    /// Fraction η of the distance to the surface each vertex moves (x′ = x − η·UDF·∇UDF).
    pub deform_step: f32,
    /// Largest displacement per axis, in voxels; below 0.5 so neighbouring vertices never swap
    /// order and cells never invert.
    pub deform_max: f32,
    /// Whether to run the inside test (docs/ALGORITHM.md §6): enclosed regions decided solid
    /// or air by the source's winding number, so parts inside hollow hulls keep their
    /// surfaces, and closed parts 1–2 voxels thick keep their thickness. On by default: on
    /// the dev corpus at 256³ it makes 10 meshes better and none worse beyond noise, and
    /// costs 12 % of the conversion of the meshes it changes (docs/QUALITY.md, issue 15).
    ///
    /// Serialized only while on, and a missing key deserializes as OFF (serde's `default`,
    /// `bool::default()`, not [`Params::default`]) on purpose: configs stored before the test
    /// became the default (a job's `job.json`, a worker's request) never wrote the key and
    /// were converted without the test, so resuming such a job keeps converting without it
    /// and keeps its fingerprint; a new job with the test on writes `inside_test: true`.
    #[serde(default, skip_serializing_if = "is_false")]
    pub inside_test: bool,
    /// Whether openings small for their part are sealed, so that a nearly closed solid stays
    /// solid instead of becoming a thin shell (docs/ALGORITHM.md §4, `crate::stages::seal`): a
    /// pocket that the walls grown by about 1/32 of the grid close off (openings up to about
    /// 1/15 of the grid across, the same share of the object at every resolution) and that the
    /// source's winding number reads as solid is taken back from the outside. Needs the
    /// inside test (it asks the winding number); without it this does nothing. On by default.
    ///
    /// Serialized only while on and read as off when missing, as [`Params::inside_test`]:
    /// a job stored before the rule existed resumes without it and keeps its fingerprint.
    #[serde(default, skip_serializing_if = "is_false")]
    pub seal_openings: bool,
    /// The fraction of the grid's side that the object's longest side spans, when a consumer's
    /// frame fixes it (`sparc3d-formats` says which consumer needs which span, and where it
    /// comes from); `None`: `(N − 2·margin_cells)/N`,
    /// the object as large as the margin allows. The margin it leaves, `(1 − span)·N/2` cells
    /// per side, must be at least 3 cells, as [`Params::margin_cells`].
    ///
    /// Serialized only when set, and missing reads as `None`: every job stored before the key
    /// existed keeps its normalization and its fingerprint.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object_span: Option<f64>,
    /// The fraction of the grid's side that the *output's* longest side spans, its box
    /// centred on the grid, when a consumer reads the output mesh as filling a cube
    /// (TRELLIS.2's `read_mesh`, `sparc3d-formats`' `trellis2`); `None`: the source's box is
    /// fitted ([`Params::object_span`]). The conversion then runs twice and puts the
    /// output's box there exactly ([`crate::stages::frame`], docs/ALGORITHM.md §13). Excludes
    /// `object_span`, `deform` and `refine`, and must leave 3 free cells per side.
    ///
    /// Serialized only when set, and missing reads as `None`: every job stored before the key
    /// existed keeps its normalization and its fingerprint.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_span: Option<f64>,
    /// The rendering-based refinement of the displacements (paper step 4, docs/ALGORITHM.md
    /// §12, [`crate::stages::refine`]) and its settings; `None`: off, the default (docs/QUALITY.md
    /// says what it measured). A job file writes `refine = true` for the default settings or
    /// a `[params.refine]` table.
    ///
    /// Serialized only when on (then with every setting, so a stored job keeps the settings
    /// it was made with), and missing reads as off: every job stored before the key existed
    /// keeps its output and its fingerprint.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "crate::stages::refine::settings::deserialize"
    )]
    pub refine: Option<RefineParams>,
}

/// Refuses an object span outside (0, 1) or one that leaves fewer than 3 free cells per side
/// at `resolution` (one for the shell, one for the band, one for the flood, as
/// [`Params::margin_cells`]).
fn check_span(span: f64, resolution: u32) -> Result<()> {
    let n = resolution as f64;
    let margin = (1.0 - span) * n / 2.0;
    if !(span > 0.0 && span < 1.0) || margin < 3.0 {
        let largest = (n - 6.0) / n;
        return Err(Error::InvalidParams(format!(
            "object_span must be in (0, 1) and leave at least 3 free cells per side \
             (at most {largest} at resolution {resolution}), got {span} ({margin:.2} cells)"
        )));
    }
    Ok(())
}

/// Whether a flag is off (serde's `skip_serializing_if` for [`Params::inside_test`] and
/// [`Params::seal_openings`]).
fn is_false(b: &bool) -> bool {
    !*b
}

impl Default for Params {
    fn default() -> Self {
        Self {
            resolution: 512,
            margin_cells: 3,
            shell_half_thickness: 0.9,
            deform: false,
            deform_step: 0.5,
            deform_max: 0.45,
            inside_test: true,
            seal_openings: true,
            object_span: None,
            output_span: None,
            refine: None,
        }
    }
}

impl Params {
    /// Default parameters at the given resolution.
    pub fn with_resolution(resolution: u32) -> Self {
        Self {
            resolution,
            ..Self::default()
        }
    }

    /// The parameters with the rules that depend on others settled: the sealing of openings
    /// asks the inside test's winding number, so without the test it is off (and a config
    /// that switches the test off stores neither key, as before the sealing existed).
    pub fn settled(self) -> Self {
        Self {
            seal_openings: self.seal_openings && self.inside_test,
            ..self
        }
    }

    /// The fraction of the grid's side that the object's longest side spans:
    /// [`Params::object_span`], else the output's [`Params::output_span`] (the source's box
    /// within a voxel of it), else `(N − 2·margin_cells)/N`.
    pub fn span(&self) -> f64 {
        self.object_span.or(self.output_span).unwrap_or_else(|| {
            let n = self.resolution as f64;
            (n - 2.0 * self.margin_cells as f64) / n
        })
    }

    /// Refuses an output span that leaves fewer than 3 free cells per side, or that is set
    /// with a setting it excludes (the source's span; displacements, which move the output
    /// after it is framed).
    fn check_output_span(&self, span: f64) -> Result<()> {
        check_span(span, self.resolution).map_err(|e| match e {
            Error::InvalidParams(m) => {
                Error::InvalidParams(m.replace("object_span", "output_span"))
            }
            other => other,
        })?;
        let excluded = [
            ("object_span", self.object_span.is_some()),
            ("deform", self.deform),
            ("refine", self.refine.is_some()),
        ];
        match excluded.iter().find(|(_, on)| *on) {
            Some((name, _)) => Err(Error::InvalidParams(format!(
                "output_span frames the output's box, which {name} would change or contradict: \
                 set one of them"
            ))),
            None => Ok(()),
        }
    }

    /// Checks every field's range; the error names the field.
    pub fn validate(&self) -> Result<()> {
        if self.margin_cells < 3 {
            return Err(Error::InvalidParams(format!(
                "margin_cells must be at least 3, got {}",
                self.margin_cells
            )));
        }
        let min_res = 2 * self.margin_cells + 2;
        if self.resolution < min_res || self.resolution > MAX_RESOLUTION {
            return Err(Error::InvalidParams(format!(
                "resolution must be in {min_res}..={MAX_RESOLUTION}, got {}",
                self.resolution
            )));
        }
        if let Some(span) = self.object_span {
            check_span(span, self.resolution)?;
        }
        if let Some(span) = self.output_span {
            self.check_output_span(span)?;
        }
        if let Some(refine) = &self.refine {
            refine.validate()?;
        }
        if !(self.shell_half_thickness > 0.0 && self.shell_half_thickness < 1.0) {
            return Err(Error::InvalidParams(format!(
                "shell_half_thickness must be in (0, 1) voxel, got {}",
                self.shell_half_thickness
            )));
        }
        if !(0.0..1.0).contains(&self.deform_step) {
            return Err(Error::InvalidParams(format!(
                "deform_step must be in [0, 1), got {}",
                self.deform_step
            )));
        }
        if !(0.0..0.5).contains(&self.deform_max) {
            return Err(Error::InvalidParams(format!(
                "deform_max must be in [0, 0.5) voxel, got {}",
                self.deform_max
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::normalization::Normalization;

    #[test]
    fn an_object_span_sets_the_fit_and_must_leave_three_cells() {
        // Unset, the span is what the margin leaves; set, the longest side spans it exactly.
        let p = Params::with_resolution(512);
        assert_eq!(p.span(), 506.0 / 512.0);
        let p = Params {
            object_span: Some(0.95),
            ..p
        };
        assert!(p.validate().is_ok());
        let norm = Normalization::fit_span(([-2.0, 0.0, 0.0], [2.0, 1.0, 1.0]), 512, p.span());
        assert!((norm.scale * 4.0 - 0.95).abs() < 1e-15);
        // 0.95 leaves 12.8 cells at 512 but 1.6 at 64; 0 and 1 are no spans.
        for (span, n) in [(0.95, 64), (0.0, 512), (1.0, 512), (f64::NAN, 512)] {
            let p = Params {
                object_span: Some(span),
                ..Params::with_resolution(n)
            };
            assert!(
                matches!(p.validate(), Err(Error::InvalidParams(m)) if m.contains("object_span"))
            );
        }
    }
}
