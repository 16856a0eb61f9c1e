//! The real renderer as a study's [`Source`]: one [`RenderSession`] for every image of the
//! study, each written into the study folder (`spp<n>/seed-<i>.streams.exr`, `.pt2n.exr`) with
//! its render time beside it, so that a resumed study reuses finished files. A finished file
//! made otherwise (its provenance differs from what the study asks for) is an error, never
//! silently reused.
use crate::session::{Backend, Embree, Job, Progress, ReferenceJob, RenderSession, StreamJob, View};
use cvtrace_streams::exr_io::read_rgb;
use cvtrace_streams::provenance::describe_all;
use cvtrace_streams::{Image, Provenance, StreamSet};
use cvtrace_study::files::{self, Cell, CellKind};
use cvtrace_study::{Rendered, Source, SourceError};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub struct RenderSource<'a, B: Backend = Embree> {
    pub session: &'a RenderSession<B>,
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
    files::spp_dir(study, n)
}

impl<'a, B: Backend> RenderSource<'a, B> {
    pub fn new(
        session: &'a RenderSession<B>,
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

    fn file(&mut self, n: u32, seed: u64, kind: CellKind) -> Result<PathBuf, SourceError> {
        let index =
            seed.checked_sub(self.first_seed).ok_or_else(|| format!("seed {seed} is before the study's first seed {}", self.first_seed))?;
        let index = u32::try_from(index).map_err(|_| format!("seed {seed}: too far after the study's first seed {}", self.first_seed))?;
        let dir = spp_dir(&self.folder, n);
        // Farm tasks render cells of one folder at the same time: the folder may appear meanwhile.
        match std::fs::create_dir(&dir) {
            Ok(()) => self.made.push(dir.clone()),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && dir.is_dir() => {}
            Err(e) => return Err(format!("{}: cannot create: {e}", dir.display()).into()),
        }
        Ok(files::cell_file(&self.folder, Cell { kind, spp: n, index }))
    }

    /// Renders one cell of the study into its file (unless it is there and finished), as the
    /// study would when it comes to it: the same file, job and timing sidecar.
    pub fn render_cell(&mut self, cell: Cell, batches: u32) -> Result<PathBuf, SourceError> {
        let seed = self.first_seed + cell.index as u64;
        let path = self.file(cell.spp, seed, cell.kind)?;
        let job = match cell.kind {
            CellKind::Streams => self.stream_job(cell.spp, batches, seed, &path),
            CellKind::Pt2n => self.pt_job(&path, cell.spp, seed),
        };
        self.ensure_rendered(job)?;
        Ok(path)
    }

    /// The PT(2n) job of the streams with `n` spp and seed `stream_seed`.
    fn pt_job(&self, path: &Path, n: u32, stream_seed: u64) -> Job {
        let job = ReferenceJob::replacing(path.to_path_buf(), self.view, 2 * n, stream_seed + cvtrace_study::PT2N_SEED_OFFSET);
        Job::Reference(ReferenceJob { label: "a PT(2n) image", ..job })
    }

    /// Renders `job` unless its output is already there, finished (with its timing file) and
    /// the same render; returns the render's seconds (recorded in a sidecar so that resumed
    /// studies still report real times).
    fn ensure_rendered(&self, job: Job) -> Result<f64, SourceError> {
        let path = job.output().to_path_buf();
        let timing = files::timing_file(&path);
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

impl<B: Backend> Source for RenderSource<'_, B> {
    fn streams(&mut self, n: u32, batches: u32, seed: u64) -> Result<Rendered<StreamSet>, SourceError> {
        let path = self.file(n, seed, CellKind::Streams)?;
        let seconds = self.ensure_rendered(self.stream_job(n, batches, seed, &path))?;
        Ok(Rendered { value: StreamSet::read(&path)?, seconds, name: path.display().to_string() })
    }

    fn pt(&mut self, spp: u32, seed: u64) -> Result<Rendered<Image>, SourceError> {
        // Named after the streams it is compared with, as the study asks for it: `2n` spp, the
        // streams' seed plus the offset.
        let stream_seed =
            seed.checked_sub(cvtrace_study::PT2N_SEED_OFFSET).ok_or_else(|| format!("seed {seed}: not the seed of a PT(2n) image"))?;
        if !spp.is_multiple_of(2) {
            return Err(format!("{spp} spp: not the PT(2n) image of a stream pair").into());
        }
        let path = self.file(spp / 2, stream_seed, CellKind::Pt2n)?;
        let seconds = self.ensure_rendered(self.pt_job(&path, spp / 2, stream_seed))?;
        Ok(Rendered { value: read_rgb(&path)?, seconds, name: path.display().to_string() })
    }
}

/// The samples a render reports to its progress: both streams of a stream file.
fn samples_of(job: &Job, s: &cvtrace_render::RenderSettings) -> u64 {
    let streams = if matches!(job, Job::Streams(_)) { 2 } else { 1 };
    s.width as u64 * s.height as u64 * s.spp as u64 * streams
}
