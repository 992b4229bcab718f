//! The analysis worker: reading dropped files and running the pipeline off the page's
//! main thread, so that the page keeps painting and answering input while a large
//! log is analysed. Only in the threaded module (`target_feature = "atomics"`), where
//! the worker (`www/analysis-worker.js`) instantiates the module on the page's shared
//! memory: a [`Job`] is handed over through that memory, not copied, and the results
//! come back the same way, so the page draws them without a copy or a parse.
//!
//! The hand-over: the page puts the job in [`JOBS`] under a fresh id and posts the id
//! and the files to the worker; the worker takes the job out ([`AnalysisJob::take`]),
//! reads the files into it chunk by chunk, runs the analysis and puts it back
//! ([`AnalysisJob::finish`]); its `done` message lets the page take it out again. One
//! thread holds a job at a time, and only through the mutex. The page's main thread
//! may not block, so it takes the mutex by spinning; it is held for a push or a
//! removal only.
//!
//! Cancel: the page sets the job's [`Job::cancel`] flag; the worker checks it between
//! chunks and between the pipeline's steps.

use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, TryLockError};

use gloo::events::EventListener;
use js_sys::{Array, Function, Object, Promise, Reflect};
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use wasm_bindgen_futures::JsFuture;

use super::page::analysis::{status, Request, Steps};
use super::page::Outcome;
use crate::analysis::calibration::CalibrationAnalysis;
use crate::io::delimited::ColumnMapping;
use crate::io::import::{import_file, merge, ChunkedImport, FileImport};
use crate::io::{ImportError, ImportReport};
use crate::pdr::PdrOptions;

/// What a job does.
pub(crate) enum Work {
    /// Read these files (their bytes come from the worker) and analyse them as one
    /// recording.
    Files {
        files: Vec<FileRead>,
        options: Box<PdrOptions>,
    },
    /// Analyse the kept import again.
    Again(Box<Request>),
}

/// One file of a [`Work::Files`] job.
pub(crate) struct FileRead {
    name: String,
    size: usize,
    mapping: Option<ColumnMapping>,
    import: Option<ChunkedImport>,
    /// Set when a chunk could not be read: the rest of the file is not asked for.
    failed: Option<ImportError>,
    /// The whole file read at once ([`AnalysisJob::read_whole`]).
    whole: Option<Result<FileImport, ImportError>>,
}

impl FileRead {
    /// A file of `size` bytes, read with `mapping` (the user's, or one remembered for
    /// its header).
    pub(crate) fn new(name: String, size: usize, mapping: Option<ColumnMapping>) -> FileRead {
        FileRead {
            name,
            size,
            mapping,
            import: None,
            failed: None,
            whole: None,
        }
    }
}

/// A job and, once the worker is done, its outcome.
pub(crate) struct Job {
    pub work: Work,
    /// Set by the page to stop the job at its next chunk or step.
    pub cancel: Arc<AtomicBool>,
    /// Set by the worker when the job is done, before its `done` message: the page
    /// then draws no more of the job's early figures, which would only hold up the
    /// answer (the message waits for the page's thread), and draws them with the rest.
    pub finished: Arc<AtomicBool>,
    /// The import analysed (when the files could be read) and the analysis; `None`
    /// while the job runs, and after a cancel.
    pub outcome: Option<Outcome>,
}

impl Job {
    /// A job doing `work`, stopped by `cancel`.
    pub(crate) fn new(work: Work, cancel: &Arc<AtomicBool>) -> Job {
        Job {
            work,
            cancel: Arc::clone(cancel),
            finished: Arc::new(AtomicBool::new(false)),
            outcome: None,
        }
    }
}

/// Values handed between the page's thread and the worker through the shared memory,
/// each under its job's id: one thread holds a value at a time, taken out and put back.
/// The mutex is taken by spinning, since the page's main thread may not block; it is
/// held for a push or a removal only.
struct HandOver<T>(Mutex<Vec<(u32, Box<T>)>>);

impl<T> HandOver<T> {
    const fn new() -> HandOver<T> {
        HandOver(Mutex::new(Vec::new()))
    }

    fn with<R>(&self, f: impl FnOnce(&mut Vec<(u32, Box<T>)>) -> R) -> R {
        loop {
            match self.0.try_lock() {
                Ok(mut values) => return f(&mut values),
                Err(TryLockError::Poisoned(poisoned)) => return f(&mut poisoned.into_inner()),
                Err(TryLockError::WouldBlock) => std::hint::spin_loop(),
            }
        }
    }

    fn put(&self, id: u32, value: Box<T>) {
        self.with(|values| values.push((id, value)));
    }

    fn take(&self, id: u32) -> Option<Box<T>> {
        self.with(|values| {
            let idx = values.iter().position(|(value_id, _)| *value_id == id)?;
            Some(values.swap_remove(idx).1)
        })
    }
}

/// The jobs handed over (see the module's documentation).
static JOBS: HandOver<Job> = HandOver::new();

/// A job's calibration, copied for the page while the job goes on, with the import it
/// came from.
static CALIBRATED: HandOver<(Arc<ImportReport>, CalibrationAnalysis)> = HandOver::new();

/// A job as the worker's script holds it, between [`AnalysisJob::take`] and
/// [`AnalysisJob::finish`].
#[wasm_bindgen]
pub struct AnalysisJob {
    id: u32,
    job: Box<Job>,
}

#[wasm_bindgen]
impl AnalysisJob {
    /// The job the page handed over as `id`, or `undefined` if there is none.
    pub fn take(id: u32) -> Option<AnalysisJob> {
        JOBS.take(id).map(|job| AnalysisJob { id, job })
    }

    /// Whether the page asked to stop.
    pub fn cancelled(&self) -> bool {
        self.job.cancel.load(Ordering::Acquire)
    }

    /// File `file_idx` (the files in the order they were posted) whole, as the CLI reads
    /// a file it maps: the streams sized once and a large file parsed on every core
    /// (the worker reads files up to a size this way, larger ones in chunks).
    pub fn read_whole(&mut self, file_idx: usize, bytes: &[u8]) {
        let Work::Files { files, .. } = &mut self.job.work else {
            return;
        };
        if let Some(file) = files.get_mut(file_idx) {
            file.whole = Some(import_file(&file.name, bytes, file.mapping.as_ref()));
        }
    }

    /// File `file_idx` could not be read (the browser's `reason`): it is left out, and
    /// named with the reason if nothing else could be read.
    pub fn unreadable(&mut self, file_idx: usize, reason: String) {
        let Work::Files { files, .. } = &mut self.job.work else {
            return;
        };
        if let Some(file) = files.get_mut(file_idx) {
            file.whole = None;
            file.failed = Some(ImportError::Unreadable {
                file_name: file.name.clone(),
                reason,
            });
        }
    }

    /// The next chunk of file `file_idx` (the files in the order they were posted);
    /// `false` once that file cannot be read further (its error is kept for the
    /// outcome), so the worker stops reading it.
    pub fn feed(&mut self, file_idx: usize, bytes: &[u8]) -> bool {
        let Work::Files { files, .. } = &mut self.job.work else {
            return false;
        };
        let Some(file) = files.get_mut(file_idx) else {
            return false;
        };
        if file.failed.is_some() {
            return false;
        }
        let (name, size, mapping) = (&file.name, file.size, &file.mapping);
        let import = file.import.get_or_insert_with(|| {
            ChunkedImport::new(name, Some(size)).with_mapping(mapping.clone())
        });
        match import.feed(bytes) {
            Ok(()) => true,
            Err(error) => {
                file.failed = Some(error);
                false
            }
        }
    }

    /// Finishes reading and runs the analysis; `on_step(text)` is called with the
    /// status line before each step, and `on_calibrated()` once the calibration is
    /// done and a copy of it waits for the page ([`CALIBRATED`]), so that its
    /// figures are drawn while the heading models and the dead reckoning run. Stops
    /// early, with no outcome, when cancelled.
    pub fn run(&mut self, on_step: &Function, on_calibrated: &Function) {
        let cancel = Arc::clone(&self.job.cancel);
        let request = match std::mem::replace(
            &mut self.job.work,
            Work::Files {
                files: Vec::new(),
                options: Box::default(),
            },
        ) {
            Work::Again(request) => *request,
            Work::Files { files, options } => {
                let read = files
                    .into_iter()
                    .map(|file| {
                        let result = match (file.whole, file.failed, file.import) {
                            (Some(whole), _, _) => whole,
                            (None, Some(error), _) => Err(error),
                            (None, None, Some(import)) => import.finish(),
                            (None, None, None) => Err(ImportError::Empty {
                                file_name: file.name.clone(),
                            }),
                        };
                        (file.name, result)
                    })
                    .collect();
                match merge(read) {
                    Ok(import) => Request {
                        import: Arc::new(import),
                        stage: crate::pipeline::Stage::Calibration,
                        previous: None,
                        options: *options,
                    },
                    Err(error) => {
                        self.job.outcome = Some((None, Err(error.into())));
                        return;
                    }
                }
            }
        };
        let mut steps = Steps::new(request);
        while let Some(step) = steps.next() {
            let _ = on_step.call1(
                &JsValue::NULL,
                &status(step, &steps.import().file_name).into(),
            );
            if cancel.load(Ordering::Acquire) {
                return;
            }
            steps.advance();
            if let Some(calibration) = steps.calibrated() {
                let early = (Arc::clone(steps.import()), calibration.clone());
                CALIBRATED.put(self.id, Box::new(early));
                let _ = on_calibrated.call0(&JsValue::NULL);
            }
        }
        let import = Arc::clone(steps.import());
        self.job.outcome = Some((Some(import), steps.finish()));
    }

    /// Hands the job back to the page (its `done` message follows).
    pub fn finish(self) {
        self.job.finished.store(true, Ordering::Release);
        JOBS.put(self.id, self.job);
    }
}

/// An update from the worker while a job runs.
pub(crate) enum Update {
    /// `fraction` of the bytes read, `file_name` the one being read.
    Progress { fraction: f64, file_name: String },
    /// The status line of the step that starts.
    Step(String),
    /// The calibration, done while the job goes on, with the import it came from.
    Calibrated(Box<(Arc<ImportReport>, CalibrationAnalysis)>),
}

/// A job the page waits for: its promise's resolve and reject, and where its updates go.
struct Waiting {
    resolve: Function,
    reject: Function,
    on_update: Box<dyn Fn(Update)>,
}

/// The page's side of the analysis worker.
pub(crate) struct AnalysisWorker {
    worker: web_sys::Worker,
    next_id: Cell<u32>,
    waiting: Rc<RefCell<HashMap<u32, Waiting>>>,
    /// Set when the worker failed (its script did not load, or it trapped): the page
    /// then analyses on its own thread.
    broken: Rc<Cell<bool>>,
    _listeners: [EventListener; 2],
}

impl AnalysisWorker {
    /// Listens to `worker` (started by `www/bootstrap.js` on the module's memory).
    pub(crate) fn new(worker: web_sys::Worker) -> AnalysisWorker {
        let waiting: Rc<RefCell<HashMap<u32, Waiting>>> = Rc::default();
        let broken = Rc::new(Cell::new(false));
        let on_message = {
            let waiting = Rc::clone(&waiting);
            EventListener::new(&worker, "message", move |event| {
                let Some(data) = event
                    .dyn_ref::<web_sys::MessageEvent>()
                    .map(|event| event.data())
                else {
                    return;
                };
                let field =
                    |name: &str| Reflect::get(&data, &name.into()).unwrap_or(JsValue::UNDEFINED);
                let Some(id) = field("id").as_f64().map(|id| id as u32) else {
                    return;
                };
                let mut waiting = waiting.borrow_mut();
                if let Some(fraction) = field("progress").as_f64() {
                    if let Some(job) = waiting.get(&id) {
                        let file_name = field("file").as_string().unwrap_or_default();
                        (job.on_update)(Update::Progress {
                            fraction,
                            file_name,
                        });
                    }
                } else if let Some(step) = field("step").as_string() {
                    if let Some(job) = waiting.get(&id) {
                        (job.on_update)(Update::Step(step));
                    }
                } else if field("calibrated").is_truthy() {
                    let early = CALIBRATED.take(id);
                    if let (Some(job), Some(early)) = (waiting.get(&id), early) {
                        (job.on_update)(Update::Calibrated(early));
                    }
                } else if let Some(job) = waiting.remove(&id) {
                    let failed = field("failed");
                    let _ = if failed.is_undefined() {
                        job.resolve.call0(&JsValue::NULL)
                    } else {
                        job.reject.call1(&JsValue::NULL, &failed)
                    };
                }
            })
        };
        let on_error = {
            let waiting = Rc::clone(&waiting);
            let broken = Rc::clone(&broken);
            EventListener::new(&worker, "error", move |event| {
                broken.set(true);
                let message = event.dyn_ref::<web_sys::ErrorEvent>().map_or_else(
                    || "the analysis worker failed".to_string(),
                    web_sys::ErrorEvent::message,
                );
                for (_, job) in waiting.borrow_mut().drain() {
                    let _ = job.reject.call1(&JsValue::NULL, &message.as_str().into());
                }
            })
        };
        AnalysisWorker {
            worker,
            next_id: Cell::new(1),
            waiting,
            broken,
            _listeners: [on_message, on_error],
        }
    }

    /// Whether jobs can go to the worker.
    pub(crate) fn works(&self) -> bool {
        !self.broken.get()
    }

    /// Runs `job` on the worker, `files` being the blobs of a [`Work::Files`] job in
    /// its order; `on_update` hears its progress. Gives the job back with its
    /// outcome, or `Err(job)` when the worker failed (which the console or the page is
    /// told here): the job as it was handed over if the worker never took it, for the
    /// page to run itself, else `None` (a bug: the page says so).
    pub(crate) async fn run(
        &self,
        job: Job,
        files: &[web_sys::Blob],
        on_update: impl Fn(Update) + 'static,
    ) -> Result<Box<Job>, Option<Box<Job>>> {
        let id = self.next_id.get();
        self.next_id.set(id.wrapping_add(1));
        JOBS.put(id, Box::new(job));
        let mut on_update: Option<Box<dyn Fn(Update)>> = Some(Box::new(on_update));
        let waiting = Rc::clone(&self.waiting);
        let promise = Promise::new(&mut |resolve, reject| {
            if let Some(on_update) = on_update.take() {
                waiting.borrow_mut().insert(
                    id,
                    Waiting {
                        resolve,
                        reject,
                        on_update,
                    },
                );
            }
        });
        let message = Object::new();
        let blobs: Array = files.iter().collect();
        let posted = Reflect::set(&message, &"id".into(), &id.into())
            .and_then(|_| Reflect::set(&message, &"files".into(), &blobs))
            .and_then(|_| self.worker.post_message(&message));
        let answer = match posted {
            Ok(()) => JsFuture::from(promise).await.map(|_| ()),
            Err(error) => Err(error),
        };
        self.waiting.borrow_mut().remove(&id);
        let (job, message) = match (answer, JOBS.take(id)) {
            (Ok(()), Some(job)) => return Ok(job),
            (Ok(()), None) => (None, "the analysis worker lost the job".to_string()),
            (Err(error), job) => {
                self.broken.set(true);
                (job, super::page::describe_js_error(error))
            }
        };
        match &job {
            Some(_) => web_sys::console::warn_1(
                &format!("compass-pdr: the analysis worker failed ({message}); analysing on the page's thread").into(),
            ),
            None => super::page::show_bug(&format!(
                "Internal error (a bug in compass-pdr): the analysis worker stopped: {message}. Reload the page to continue, and please report it."
            )),
        }
        Err(job)
    }
}
