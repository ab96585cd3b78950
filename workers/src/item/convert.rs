//! The one conversion path: load a mesh file, convert it with Sparcubes, extract the mesh,
//! encode the tensors, timing each stage ([`convert_file`]). The item worker ([`super::row::convert_item`],
//! run inside the isolated process of [`crate::isolate::child`]), `sparc3d convert` and `sparc3d bench`
//! all go through it; each asks only for the steps it needs ([`Steps`]).

use super::appearance::{appearance_products, Source};
use crate::item::quality::SourceFacts;
use sparc3d_schema::{
    AttributeTensors, EncodedTensor, QualityFacts, RowRenders, RowTensors, SampleTensors,
    SchemaError,
};
use sparcubes::attributes::CellAttributes;
use sparcubes::io::{Buffers, LoadStats, LoadedMesh};
use sparcubes::products::shape_signature::{signature_of, surface_pass};
use sparcubes::samples::{SampleParams, Samples};
use sparcubes::{Conversion, TriMesh};
use std::path::Path;
use std::time::Instant;

pub use super::steps::{Converted, Encoding, Failed, StageError, StageSeconds, Steps};

/// Loads the mesh at `path` and takes it through `steps`.
pub fn convert_file(path: &Path, steps: Steps) -> Result<Converted, Box<Failed>> {
    let started = Instant::now();
    match sparcubes::io::read_source(path) {
        Ok(bytes) => convert_bytes(bytes, path, Buffers::Folder, steps, started),
        Err(e) => Err(Box::new(Failed {
            error: StageError::Load(e),
            seconds: StageSeconds::default(),
        })),
    }
}

/// Takes the bytes read from `path` ([`sparcubes::io::read_source`] or fetched, started at
/// `started`, which the load stage's time counts from) through `steps`; they are dropped once
/// parsed. A glTF file's external buffers come from `buffers`.
pub fn convert_bytes(
    bytes: Vec<u8>,
    path: &Path,
    buffers: Buffers,
    steps: Steps,
    started: Instant,
) -> Result<Converted, Box<Failed>> {
    let mut seconds = StageSeconds::default();
    let fail = |error, seconds| Box::new(Failed { error, seconds });
    let loaded = sparcubes::io::load_read_with(&bytes, path, buffers);
    let kept = (steps.attributes.is_some() || steps.renders.is_some()).then_some(bytes);
    let input = match loaded {
        Ok(loaded) => measure_input(loaded, &steps, started, &mut seconds),
        Err(e) => return Err(fail(StageError::Load(e), seconds)),
    };

    let t = Instant::now();
    let conversion = match sparcubes::convert(&input.source, steps.params) {
        Ok(c) => c,
        Err(e) => return Err(fail(StageError::Convert(e), seconds)),
    };
    seconds.timings.convert_s = t.elapsed().as_secs_f64();
    let stages = conversion.stats.stage_seconds.iter();
    seconds.timings.stages = stages.map(|(k, v)| (k.to_string(), *v)).collect();
    seconds
        .in_order
        .extend(seconds.timings.stages.iter().cloned());
    let input_faces = input.source.triangles.len() as u64;
    let input_vertices = input.source.positions.len() as u64;
    drop(input.source);

    let mut mesh = extract_stage(&steps, &conversion, &mut seconds);
    let output_faces = mesh
        .as_ref()
        .filter(|_| steps.extract)
        .map(|m| m.triangles.len() as u64);
    let (quality, signature) = measure_output(
        &steps,
        mesh.as_ref(),
        input.facts,
        &input.load_stats,
        &conversion,
        &mut seconds,
    );
    let samples = match samples_of(steps.samples, &conversion, mesh.as_ref(), &mut seconds) {
        Ok(s) => s,
        Err(e) => return Err(fail(StageError::Samples(e), seconds)),
    };
    let (attributes, renders) = match kept.as_deref() {
        Some(bytes) => {
            let source = Source {
                bytes,
                path,
                buffers,
            };
            match appearance_products(&source, &steps, &conversion, &mut seconds) {
                Ok(products) => products,
                Err(e) => return Err(fail(e, seconds)),
            }
        }
        None => (None, None),
    };
    let store_mesh = steps.encode.is_some_and(|e| e.store_mesh);
    if !(steps.keep_mesh || store_mesh) {
        mesh = None;
    }
    let products = Products {
        mesh: mesh.as_ref(),
        samples: samples.as_ref(),
        cells: attributes.as_ref().map(|a| &a.0),
    };
    let tensors = match encode_stage(&steps, &conversion, products, renders, &mut seconds) {
        Ok(tensors) => tensors,
        Err(e) => return Err(fail(StageError::Encode(e), seconds)),
    };
    Ok(Converted {
        load_stats: input.load_stats,
        input_faces,
        input_vertices,
        input_components: input.components,
        conversion,
        output_faces,
        mesh: if steps.keep_mesh { mesh } else { None },
        tensors,
        attributes,
        quality,
        signature,
        seconds,
    })
}

/// The loaded source with what is measured of it before the conversion.
struct Input {
    source: TriMesh,
    load_stats: LoadStats,
    /// The source's quality facts and the seconds they took, when asked for.
    facts: Option<(SourceFacts, f64)>,
    components: Option<u64>,
}

/// The source's quality facts and component count as `steps` asks; the load stage's time is
/// from `started` to now, less the facts' own time (counted in the stage `quality`).
fn measure_input(
    loaded: LoadedMesh,
    steps: &Steps,
    started: Instant,
    seconds: &mut StageSeconds,
) -> Input {
    let source = loaded.mesh;
    let quality_started = Instant::now();
    let facts = steps
        .quality
        .then(|| crate::item::quality::source_facts(&source));
    let quality_s = quality_started.elapsed().as_secs_f64();
    let components = match &facts {
        Some(f) => Some(f.components),
        None => steps
            .input_components
            .then(|| sparcubes::topology::component_count(&sparcubes::topology::weld(&source))),
    };
    seconds.timings.load_s = started.elapsed().as_secs_f64() - quality_s;
    seconds.add("load", seconds.timings.load_s);
    Input {
        source,
        load_stats: loaded.stats,
        facts: facts.map(|f| (f, quality_s)),
        components,
    }
}

/// The extracted mesh, when `steps` extract, draw samples or read a signature (all three
/// read it), timed as the stage `extract`.
fn extract_stage(
    steps: &Steps,
    conversion: &Conversion,
    seconds: &mut StageSeconds,
) -> Option<TriMesh> {
    let t = Instant::now();
    let extract = steps.extract || steps.samples.is_some() || steps.signature;
    let mesh = extract.then(|| sparcubes::extract(&conversion.cubes));
    seconds.timings.extract_s = t.elapsed().as_secs_f64();
    if extract {
        seconds.add("extract", seconds.timings.extract_s);
    }
    mesh
}

/// What the conversion's later stages made, for the encoder.
struct Products<'a> {
    mesh: Option<&'a TriMesh>,
    samples: Option<&'a Samples>,
    cells: Option<&'a CellAttributes>,
}

/// The tensors of a row, when `steps` encode, with the condition views beside them, timed
/// as the stage `encode`.
fn encode_stage(
    steps: &Steps,
    conversion: &Conversion,
    products: Products,
    renders: Option<RowRenders>,
    seconds: &mut StageSeconds,
) -> Result<Option<RowTensors>, SchemaError> {
    let Some(encoding) = steps.encode else {
        return Ok(None);
    };
    let t = Instant::now();
    let drawn = products.samples.zip(steps.samples);
    let mut tensors = encode(conversion, products.mesh, drawn, products.cells, encoding)?;
    tensors.renders = renders;
    seconds.timings.encode_s = t.elapsed().as_secs_f64();
    seconds.add("encode", seconds.timings.encode_s);
    Ok(Some(tensors))
}

/// The quality facts (given the `source`'s, measured in `seconds` before the conversion) and
/// the shape signature of the extracted `mesh`, as `steps` asks, timed as the stages `quality`
/// and `signature`. Both read one pass over the output's triangles (`surface_pass`: the volume
/// for both, the area and the sample for the signature), timed with the quality facts when
/// they are asked for (the pass is theirs; taking the sample on the way adds little:
/// docs/PERFORMANCE.md, "Near-duplicate groups") and with the signature otherwise. The
/// signature is read right after the pass, while its sample is still in the cache.
fn measure_output(
    steps: &Steps,
    mesh: Option<&TriMesh>,
    source: Option<(SourceFacts, f64)>,
    load_stats: &LoadStats,
    conversion: &Conversion,
    seconds: &mut StageSeconds,
) -> (Option<QualityFacts>, Option<Vec<f32>>) {
    let t = Instant::now();
    let pass = mesh
        .filter(|_| steps.quality || steps.signature)
        .map(|m| surface_pass(m, steps.signature));
    let pass_s = t.elapsed().as_secs_f64();
    let (pass_for_quality, pass_for_signature) = match source {
        Some(_) => (pass_s, 0.0),
        None => (0.0, pass_s),
    };
    let t = Instant::now();
    let signature = pass
        .as_ref()
        .filter(|_| steps.signature)
        .and_then(signature_of);
    let signature_s = pass_for_signature + t.elapsed().as_secs_f64();
    let quality = source.map(|(source, source_s)| {
        let t = Instant::now();
        let cubes = &conversion.cubes;
        let output = mesh.zip(pass.as_ref()).map(|(m, p)| {
            crate::item::quality::output_facts(m, p.volume, &cubes.normalization, cubes.resolution)
        });
        let facts = crate::item::quality::facts(&source, load_stats, &conversion.stats, output);
        seconds.add_stage(
            "quality",
            source_s + pass_for_quality + t.elapsed().as_secs_f64(),
        );
        facts
    });
    if signature.is_some() {
        seconds.add_stage("signature", signature_s);
    }
    (quality, signature.map(|s| s.to_vec()))
}

/// Draws the samples (`params`, a job with `[samples]`) from the extracted `mesh` and the
/// converted cubes, timed as the stage `samples`; none when either is missing.
fn samples_of(
    params: Option<&SampleParams>,
    conversion: &Conversion,
    mesh: Option<&TriMesh>,
    seconds: &mut StageSeconds,
) -> Result<Option<Samples>, sparcubes::Error> {
    let (Some(params), Some(m)) = (params, mesh) else {
        return Ok(None);
    };
    let t = Instant::now();
    let samples = sparcubes::samples::sample(&conversion.cubes, m, params)?;
    seconds.add_stage("samples", t.elapsed().as_secs_f64());
    Ok(Some(samples))
}

/// The cubes' tensors, with the mesh's when it is to be stored.
fn encode(
    conversion: &Conversion,
    mesh: Option<&TriMesh>,
    samples: Option<(&Samples, &SampleParams)>,
    cells: Option<&CellAttributes>,
    encoding: Encoding,
) -> Result<RowTensors, SchemaError> {
    let level = encoding.zstd_level;
    let mut tensors = RowTensors::from_cubes(&conversion.cubes, level)?;
    if let (true, Some(m)) = (encoding.store_mesh, mesh) {
        tensors.mesh_vertices = Some(EncodedTensor::from_f32x3(&m.positions, level)?);
        tensors.mesh_faces = Some(EncodedTensor::from_u32x3(&m.triangles, level)?);
    }
    if let Some((s, params)) = samples {
        tensors.samples = Some(SampleTensors::from_samples(s, params, level)?);
    }
    if let Some(a) = cells {
        tensors.attributes = Some(AttributeTensors::from_attributes(a, level)?);
    }
    Ok(tensors)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sparc3d_schema::ErrorClass;
    use sparcubes::Params;

    fn example(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../examples")
            .join(name)
    }

    #[test]
    fn the_path_runs_the_steps_asked_for_in_order() -> Result<(), Box<dyn std::error::Error>> {
        let params = Params::with_resolution(32);
        let mut steps = Steps {
            params: &params,
            input_components: true,
            extract: true,
            samples: None,
            keep_mesh: false,
            encode: Some(Encoding {
                zstd_level: 3,
                store_mesh: true,
            }),
            attributes: None,
            quality: false,
            signature: false,
            renders: None,
        };
        let done = convert_file(&example("cube.off"), steps).map_err(|f| f.error)?;
        let names: Vec<&str> = done
            .seconds
            .in_order
            .iter()
            .map(|(k, _)| k.as_str())
            .collect();
        assert_eq!(names.first(), Some(&"load"));
        assert_eq!(names[names.len() - 2..], ["extract", "encode"]);
        assert_eq!(names.len() - 3, done.conversion.stats.stage_seconds.len());
        assert_eq!((done.input_faces, done.input_components), (12, Some(1)));
        assert!(done.mesh.is_none(), "not kept");
        let tensors = done.tensors.ok_or("no tensors")?;
        assert!(tensors.mesh_faces.is_some(), "stored although not kept");
        assert!(done.output_faces.is_some_and(|n| n > 0));

        steps.encode = None;
        steps.keep_mesh = true;
        let kept = convert_file(&example("cube.off"), steps).map_err(|f| f.error)?;
        assert_eq!(
            kept.mesh.map(|m| m.triangles.len() as u64),
            done.output_faces
        );
        assert_eq!(kept.conversion.cubes.coords, done.conversion.cubes.coords);
        Ok(())
    }

    #[test]
    fn the_signature_shares_the_quality_facts_volume_and_changes_none_of_them(
    ) -> Result<(), Box<dyn std::error::Error>> {
        let params = Params::with_resolution(32);
        let steps = |quality, signature| Steps {
            params: &params,
            input_components: false,
            extract: true,
            samples: None,
            keep_mesh: true,
            encode: None,
            attributes: None,
            quality,
            signature,
            renders: None,
        };
        let both = convert_file(&example("sphere.obj"), steps(true, true)).map_err(|f| f.error)?;
        let quality =
            convert_file(&example("sphere.obj"), steps(true, false)).map_err(|f| f.error)?;
        let alone =
            convert_file(&example("sphere.obj"), steps(false, true)).map_err(|f| f.error)?;
        assert_eq!(
            both.quality, quality.quality,
            "the same facts with the signature"
        );
        assert!(alone.quality.is_none() && quality.signature.is_none());
        let mesh = both.mesh.as_ref().ok_or("no mesh")?;
        let want = sparcubes::products::shape_signature::shape_signature(mesh).map(|s| s.to_vec());
        assert!(want.is_some());
        assert_eq!(both.signature, want);
        assert_eq!(alone.signature, want);
        let stages = |c: &Converted| {
            c.seconds
                .in_order
                .iter()
                .map(|(k, _)| k.clone())
                .collect::<Vec<_>>()
        };
        assert!(stages(&both).ends_with(&["quality".to_string(), "signature".to_string()]));
        assert!(stages(&alone).ends_with(&["signature".to_string()]));
        Ok(())
    }

    #[test]
    fn a_refined_row_gives_back_the_refined_mesh() -> Result<(), Box<dyn std::error::Error>> {
        // The refinement runs inside the conversion, so the row stores its displacements and
        // decoding the row extracts the mesh the conversion gave (what `show` relies on).
        let params = Params {
            refine: Some(sparcubes::refine::RefineParams {
                views: 6,
                image: Some(64),
                steps: 5,
                rate: 0.05,
            }),
            ..Params::with_resolution(32)
        };
        let steps = Steps {
            params: &params,
            input_components: false,
            extract: true,
            samples: None,
            keep_mesh: true,
            encode: Some(Encoding {
                zstd_level: 3,
                store_mesh: false,
            }),
            attributes: None,
            quality: false,
            signature: false,
            renders: None,
        };
        let done = convert_file(&example("cube.off"), steps).map_err(|f| f.error)?;
        let stats = done
            .conversion
            .stats
            .refine
            .as_ref()
            .ok_or("no refine stats")?;
        assert!(stats.moved_vertices > 0, "{stats:?}");
        let cubes = &done.conversion.cubes;
        let decoded = done
            .tensors
            .ok_or("no tensors")?
            .to_cubes(cubes.resolution, cubes.normalization)?;
        assert_eq!(&decoded, cubes);
        assert_eq!(Some(sparcubes::extract(&decoded)), done.mesh);
        Ok(())
    }

    #[test]
    fn a_failure_names_its_stage_and_class() {
        let params = Params::with_resolution(32);
        let steps = Steps {
            params: &params,
            input_components: false,
            extract: false,
            samples: None,
            keep_mesh: false,
            encode: None,
            attributes: None,
            quality: false,
            signature: false,
            renders: None,
        };
        let Err(failed) = convert_file(&example("missing.obj"), steps) else {
            panic!("a missing file converted")
        };
        assert!(matches!(failed.error, StageError::Load(_)));
        assert_eq!(
            failed.error.class(),
            ErrorClass::Geometry(sparcubes::ErrorClass::IoError)
        );
        assert!(failed.seconds.in_order.is_empty());
    }
}
