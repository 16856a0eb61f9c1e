//! The real renderer as a study's [`Source`]: one [`RenderSession`] for every image of the
//! study, each written into the study folder (`spp<n>/seed-<i>.streams.exr`, `.pt2n.exr`) with
//! its render time beside it, so that a resumed study reuses finished files. A finished file
//! made otherwise (its provenance differs from what the study asks for) is an error, never
//! silently reused.
use crate::session::{Job, Progress, ReferenceJob, RenderSession, StreamJob, View};
use cvtrace_streams::exr_io::read_rgb;
use cvtrace_streams::provenance::describe_all;
use cvtrace_streams::{Image, Provenance, StreamSet};
use cvtrace_study::{Rendered, Source, SourceError};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub struct RenderSource<'a> {
    pub session: &'a RenderSession,
    /// The study folder.
    pub folder: PathBuf,
    pub view: View,
    /// Seed of the first seed's streams: file `seed-<i>` holds seed `first_seed + i`.
    pub first_seed: u64,
    /// A fresh progress display for each render.
    pub progress: Box<dyn Fn() -> Box<dyn Progress> + 'a>,
    /// The spp folders this source made, which a failed study may take back (when empty).
    made: Vec<PathBuf>,
}

/// The folder of the renders with `n` spp per stream.
pub fn spp_dir(study: &Path, n: u32) -> PathBuf {
    study.join(format!("spp{n:05}"))
}

impl<'a> RenderSource<'a> {
    pub fn new(
        session: &'a RenderSession,
        folder: PathBuf,
        view: View,
        first_seed: u64,
        progress: Box<dyn Fn() -> Box<dyn Progress> + 'a>,
    ) -> Self {
        RenderSource { session, folder, view, first_seed, progress, made: Vec::new() }
    }

    /// The folders this source created.
    pub fn made_folders(&self) -> &[PathBuf] {
        &self.made
    }

    /// The stream job of `seed` with `spp` samples per stream into `output`.
    pub fn stream_job(&self, spp: u32, batches: u32, seed: u64, output: &Path) -> Job {
        Job::Streams(StreamJob {
            output: output.to_path_buf(),
            view: self.view,
            spp: Some(spp),
            batches,
            seed,
            overwrite: true,
            part: None,
        })
    }

    fn file(&mut self, n: u32, seed: u64, suffix: &str) -> Result<PathBuf, SourceError> {
        let i =
            seed.checked_sub(self.first_seed).ok_or_else(|| format!("seed {seed} is before the study's first seed {}", self.first_seed))?;
        let dir = spp_dir(&self.folder, n);
        if !dir.exists() {
            std::fs::create_dir(&dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
            self.made.push(dir.clone());
        }
        Ok(dir.join(format!("seed-{i:03}.{suffix}")))
    }

    /// Renders `job` unless its output is already there, finished (with its timing file) and
    /// the same render; returns the render's seconds (recorded in a sidecar so that resumed
    /// studies still report real times).
    fn ensure_rendered(&self, job: Job) -> Result<f64, SourceError> {
        let path = job.output().to_path_buf();
        let timing = path.with_extension("seconds");
        if path.exists() {
            if let Some(t) = std::fs::read_to_string(&timing).ok().and_then(|s| s.trim().parse::<f64>().ok()) {
                let plan = self.session.plan(&job)?;
                let differences = plan.provenance.differences(&Provenance::read_header(&path)?);
                if !differences.is_empty() {
                    return Err(format!(
                        "{}: this finished render differs from what the study asks for ({}); use another -o or delete the folder's renders",
                        path.display(),
                        describe_all(&differences, "in the file")
                    )
                    .into());
                }
                tracing::info!("reusing {}", path.display());
                // Counted as done, so that a progress over many renders reaches its end.
                let progress = (self.progress)();
                let samples = samples_of(&job, &plan.settings);
                progress.start(samples, samples);
                progress.finish();
                return Ok(t);
            }
        }
        let t = Instant::now();
        self.session.render(&job, (self.progress)().as_ref())?;
        let secs = t.elapsed().as_secs_f64();
        cvtrace_streams::atomic::write_atomically(&timing, true, |tmp| std::fs::write(tmp, format!("{secs}\n")))?;
        Ok(secs)
    }
}

impl Source for RenderSource<'_> {
    fn streams(&mut self, n: u32, batches: u32, seed: u64) -> Result<Rendered<StreamSet>, SourceError> {
        let path = self.file(n, seed, "streams.exr")?;
        let seconds = self.ensure_rendered(self.stream_job(n, batches, seed, &path))?;
        Ok(Rendered { value: StreamSet::read(&path)?, seconds, name: path.display().to_string() })
    }

    fn pt(&mut self, spp: u32, seed: u64) -> Result<Rendered<Image>, SourceError> {
        // Named after the streams it is compared with, as the study asks for it: `2n` spp, the
        // streams' seed plus the offset.
        let stream_seed =
            seed.checked_sub(cvtrace_study::PT2N_SEED_OFFSET).ok_or_else(|| format!("seed {seed}: not the seed of a PT(2n) image"))?;
        let path = self.file(spp / 2, stream_seed, "pt2n.exr")?;
        let job = ReferenceJob { label: "a PT(2n) image", ..ReferenceJob::replacing(path.clone(), self.view, spp, seed) };
        let seconds = self.ensure_rendered(Job::Reference(job))?;
        Ok(Rendered { value: read_rgb(&path)?, seconds, name: path.display().to_string() })
    }
}

/// The samples a render reports to its progress: both streams of a stream file.
fn samples_of(job: &Job, s: &cvtrace_render::RenderSettings) -> u64 {
    let streams = if matches!(job, Job::Streams(_)) { 2 } else { 1 };
    s.width as u64 * s.height as u64 * s.spp as u64 * streams
}
