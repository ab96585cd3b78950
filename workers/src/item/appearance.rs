//! What the conversion reads of a source's appearance after its shape: the attributes of the
//! active cells and the condition views, from one read of its materials, and the render request
//! of a job's `[renders]`.

use super::steps::{Sampled, StageError, StageSeconds, Steps};
use sparc3d_render::cond::{asset, Request};
use sparc3d_schema::AppearanceFacts;
use sparc3d_schema::{RenderedView, RowRenders};
use sparcubes::io::Buffers;
use sparcubes::Conversion;
use std::path::Path;
use std::time::Instant;

/// The source's bytes kept for the stages after the conversion, and where they came from.
pub(crate) struct Source<'a> {
    /// The bytes converted.
    pub(crate) bytes: &'a [u8],
    /// Where they came from.
    pub(crate) path: &'a Path,
    /// Where a glTF file's external buffers come from.
    pub(crate) buffers: Buffers<'a>,
}

/// The attributes and the condition views `steps` asks for, from the source's bytes parsed
/// again: its appearance is read once for both, and timed with the attributes when they are
/// asked for, else with the views. Attributes fail the item when the appearance cannot be
/// read; views are then drawn in the plain grey.
pub(crate) fn appearance_products(
    source: &Source,
    steps: &Steps,
    conversion: &Conversion,
    seconds: &mut StageSeconds,
) -> Result<(Option<Sampled>, Option<RowRenders>), StageError> {
    let t = Instant::now();
    let budget = steps.attributes.unwrap_or_default();
    let read = sparcubes::materials::read_within(source.bytes, source.path, source.buffers, budget);
    let (appearance, read_error) = match read {
        Ok(a) => (Some(a), None),
        Err(e) if steps.attributes.is_some() => return Err(StageError::Attributes(e)),
        Err(e) => (None, Some(e)),
    };
    let attributes = appearance
        .as_ref()
        .filter(|_| steps.attributes.is_some())
        .map(|a| {
            let cells = sparcubes::attributes::sample(&conversion.cubes, a);
            let facts = AppearanceFacts::new(&a.facts, &cells);
            seconds.add_stage("attributes", t.elapsed().as_secs_f64());
            (cells, facts)
        });
    let renders = match &steps.renders {
        Some(request) => {
            let not_read = match (&read_error, &appearance) {
                (Some(e), _) => vec![format!(
                    "the appearance could not be read ({e}): the views are in the plain grey"
                )],
                (None, Some(a)) => a.facts.not_read.clone(),
                (None, None) => Vec::new(),
            };
            let coloured = appearance.and_then(asset::with_colours);
            let since = match steps.attributes {
                Some(_) => Instant::now(),
                None => t,
            };
            let mut views = renders_of(source, coloured.as_ref(), request, since, seconds)?;
            views.not_read = not_read;
            Some(views)
        }
        None => None,
    };
    Ok((attributes, renders))
}

/// The condition views of the source (parsed again from its bytes) in `appearance`'s
/// colours, timed from `since` as the stage `renders`; a view that sees nothing fails them.
fn renders_of(
    source: &Source,
    appearance: Option<&sparcubes::materials::Appearance>,
    request: &Request,
    since: Instant,
    seconds: &mut StageSeconds,
) -> Result<RowRenders, StageError> {
    let mesh = sparcubes::io::load_read_with(source.bytes, source.path, source.buffers)
        .map_err(StageError::Load)?
        .mesh;
    let views =
        asset::render_asset(&mesh, appearance, request).map_err(StageError::RenderEncode)?;
    if let Some(problem) = views.problem() {
        return Err(StageError::Renders(problem));
    }
    seconds.add_stage("renders", since.elapsed().as_secs_f64());
    Ok(RowRenders {
        views: views
            .pngs
            .into_iter()
            .zip(views.seconds)
            .map(|(png, seconds)| RenderedView { png, seconds })
            .collect(),
        transforms: views.transforms,
        not_read: Vec::new(),
    })
}

/// The render request of a job's `[renders]` for a source whose sha256 is `sha` (hex): the
/// item's seed is the head of that sha256 mixed with the section's seed, as `sparc3d render`
/// seeds a file. `None` when the job renders nothing.
pub(crate) fn render_request(
    config: &sparc3d_schema::RenderConfig,
    sha: &str,
) -> Result<Option<Request>, String> {
    if !config.enabled {
        return Ok(None);
    }
    let recipe = sparc3d_render::cond::Recipe::named(&config.recipe)
        .ok_or_else(|| format!("renders.recipe {:?} names no render recipe", config.recipe))?;
    let mut head = [0u8; 8];
    for (i, b) in head.iter_mut().enumerate() {
        *b = sha
            .get(2 * i..2 * i + 2)
            .and_then(|h| u8::from_str_radix(h, 16).ok())
            .ok_or_else(|| format!("the source's sha256 {sha:?} is not hex"))?;
    }
    Ok(Some(Request {
        recipe,
        views: config.views,
        size: config.size,
        seed: asset::seed_of(head, config.seed),
        passes: Default::default(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_job_may_name_every_render_recipe_and_no_other() {
        let names: Vec<&str> = sparc3d_render::cond::Recipe::ALL
            .iter()
            .map(|(n, _)| *n)
            .collect();
        assert_eq!(names, sparc3d_schema::RenderConfig::RECIPES);
        let on = sparc3d_schema::RenderConfig {
            enabled: true,
            ..Default::default()
        };
        let sha = "0102030405060708".to_string() + &"0".repeat(48);
        let request = render_request(&on, &sha).unwrap().unwrap();
        assert_eq!(request.seed, asset::seed_of([1, 2, 3, 4, 5, 6, 7, 8], 0));
        assert!(render_request(&on, "zz").is_err());
        let off = sparc3d_schema::RenderConfig::default();
        assert!(render_request(&off, &sha).unwrap().is_none());
    }
}
