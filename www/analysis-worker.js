// The analysis worker (src/web/worker.rs): reads the files the page hands over and runs
// the analysis off the page's main thread, so that the page keeps painting and
// answering while a large log is analysed. It instantiates the threaded module the page
// compiled on the page's shared memory: a job is taken from that memory by its id, and
// put back there with its results, so nothing is copied on the way back.
import { initSync, AnalysisJob, pdr_pipeline_files, pdr_pipeline_simulated_drive } from './pkg-threads/compass_pdr.js';

/** Bytes read at a time: the page hears of the progress after each. */
const CHUNK_BYTES = 4 * 1024 * 1024;
/** A file up to this size is read whole, as the CLI reads a file (its streams sized
 * once, parsed on every core); a larger one in chunks, with the progress bar moving,
 * and memory holding its samples rather than its text. */
const WHOLE_FILE_BYTES = 16 * 1024 * 1024;

/** Jobs run one after the other, each to its end (the page cancels one through its flag). */
let running = Promise.resolve();
/** Jobs posted so far. */
let jobsPosted = 0;
/** Whether the warm-up was started (once, after the first job: the demo). */
let warmUpStarted = false;

self.onmessage = ({ data }) => {
  if (data.module) {
    initSync({ module: data.module, memory: data.memory });
    return;
  }
  jobsPosted += 1;
  // A job that throws outside its own handling (a trap) is reported, and the next
  // jobs still run.
  running = running
    .then(() => runJob(data))
    .catch((error) => postMessage({ id: data.id, failed: `${error}` }))
    .finally(() => {
      if (!warmUpStarted) {
        warmUpStarted = true;
        const jobsBefore = jobsPosted;
        // Once a job has come after the first, the user has dropped a log: no warm-up.
        setTimeout(() => warmUp(() => jobsPosted !== jobsBefore), WARM_UP_AFTER_MS);
      }
    });
};

/** The simulated drive of the warm-up (s): two laps of the loop. */
const WARM_UP_DRIVE_S = 240;

/** The warm-up starts this long after the first job (the demo), once the page has
 * drawn its figures. */
const WARM_UP_AFTER_MS = 1000;

/** Times the warm-up analyses each of its logs: V8 optimises a function once it has run
 * enough, and small logs run each once too little (bench/drop_costs.mjs WARM=1 DROP=1,
 * 2026-12-06, two runs each: the Pixel 6a drive's first drop 162-180 ms after one
 * round, 128-145 after two, 126-140 after three; log171.bin 104-122, 84-86, 73-87). */
const WARM_UP_ROUNDS = 3;

/** A pause that lets a job's message in. */
const turn = () => new Promise((resolve) => setTimeout(resolve, 0));

/** The bytes of one warm-up log's files, or null when they cannot be fetched. */
async function fetchLog(files) {
  try {
    const contents = await Promise.all(files.map(async (file) => {
      const response = await fetch(new URL(`pkg-threads/warm-up/${file}`, import.meta.url));
      if (!response.ok) throw new Error(`${file}: ${response.status}`);
      return new Uint8Array(await response.arrayBuffer());
    }));
    return { names: files.map((file) => file.split('/').pop()), contents };
  } catch {
    return null;
  }
}

/** While the user picks a file, the module analyses small logs of every format it reads
 * (pkg-threads/warm-up/, from tests/data: scripts/setup.sh) and a simulated drive (the
 * code of a car's log, which no small log takes), one at a time, WARM_UP_ROUNDS times:
 * V8 compiles each importer's code and optimises the hot parts then, not during the
 * user's first drop (issue 45: that drop took up to 1.8 times the next one). Each
 * format's log has the kinds of lines real ones have (tests/data/formats.py): with a
 * Microsoft-style Android dump and a TYREX folder in place of a dump of two sensors
 * and none, the first drops of those recordings parsed in 22-36 ms instead of 31-45
 * (bench/drop_costs.mjs WARM=1 DROP=1, 2026-12-06, two runs). A job
 * posted ends the warm-up (it waits for at most the log being analysed), and nothing is
 * fetched once one was (`jobCame`); nothing is shown; a log that cannot be fetched
 * (offline before the first visit kept it) is skipped. A timer cannot fire while this
 * thread analyses a job, so without that check a drop within the first second would
 * start the warm-up as its job ends, beside the page drawing its figures. */
async function warmUp(jobCame) {
  const started = performance.now();
  if (jobCame()) return;
  let list;
  try {
    list = await (await fetch(new URL('pkg-threads/warm-up/warm-up.json', import.meta.url))).json();
  } catch {
    return;
  }
  // Each log fetched in the first round, when its turn comes, and kept for the others.
  const logs = list.map(() => undefined);
  for (let round = 0; round < WARM_UP_ROUNDS; round += 1) {
    for (const [logIdx, files] of list.entries()) {
      await turn();
      if (jobCame()) return;
      if (logs[logIdx] === undefined) logs[logIdx] = await fetchLog(files);
      if (jobCame()) return;
      if (!logs[logIdx]) continue;
      try {
        pdr_pipeline_files(logs[logIdx].names, logs[logIdx].contents);
      } catch {
        // A log the pipeline refuses still ran its importer.
      }
    }
    await turn();
    if (jobCame()) return;
    try {
      pdr_pipeline_simulated_drive(WARM_UP_DRIVE_S);
    } catch {
      // As above.
    }
  }
  postMessage({ warmedUp: performance.now() - started });
}

/** Bytes of the files read whole that may be asked for ahead of the one being parsed. */
const READ_AHEAD_BYTES = 64 * 1024 * 1024;

/** The reads of a job's files, asked for ahead: the browser reads the next files while
 * this thread parses the ones before, within READ_AHEAD_BYTES beyond the file being
 * parsed (bench/drop_costs.mjs, 2026-12-06, two runs each: Sensor Logger's folder
 * dropped in 307-317 ms against 328-364 with one file asked for ahead, a TYREX trial's
 * in 104-110 against 117-126). */
class ReadAhead {
  constructor(files) {
    this.files = files;
    this.reads = [];
    this.asked = 0;
  }

  /** File `fileIdx`'s read (null for a file read in chunks), and the next ones asked for. */
  take(fileIdx) {
    const wholeSize = (file) => (readsWhole(file) ? file.size : 0);
    let bytesAhead = this.files.slice(fileIdx + 1, this.asked).reduce((sum, file) => sum + wholeSize(file), 0);
    while (this.asked < this.files.length && (this.asked <= fileIdx || bytesAhead + wholeSize(this.files[this.asked]) <= READ_AHEAD_BYTES)) {
      if (this.asked > fileIdx) bytesAhead += wholeSize(this.files[this.asked]);
      this.reads[this.asked] = readWhole(this.files[this.asked]);
      this.asked += 1;
    }
    const read = this.reads[fileIdx];
    this.reads[fileIdx] = null;
    return read;
  }
}

/** Whether `file` is read whole (else in chunks). */
function readsWhole(file) {
  return file.size > 0 && file.size <= WHOLE_FILE_BYTES;
}

/** The bytes of a file read whole, or null when it is to be read in chunks. */
function readWhole(file) {
  if (!readsWhole(file)) return null;
  const bytes = file.arrayBuffer();
  // A read asked for ahead and then not waited for (the job was cancelled) must not
  // report its failure as unhandled; waited for, it still throws.
  bytes.catch(() => {});
  return bytes;
}

/** The browser's reason a read failed, as a clause (the page's message goes on after it). */
function reasonOf(error) {
  return `${error?.message ?? error}`.replace(/[.\s]+$/, '');
}

/** Now, on a clock the page shares (its `performance.timeOrigin` is not this worker's). */
const now = () => performance.timeOrigin + performance.now();

async function runJob({ id, files }) {
  const startAt = now();
  // Time spent waiting for the browser to hand over the dropped files' bytes.
  let blobMs = 0;
  const job = AnalysisJob.take(id);
  if (!job) {
    postMessage({ id, done: true });
    return;
  }
  try {
    const reader = new FileReaderSync();
    const totalBytes = files.reduce((sum, file) => sum + file.size, 0);
    let bytesDone = 0;
    const ahead = new ReadAhead(files);
    reading: for (const [fileIdx, file] of files.entries()) {
      const whole = ahead.take(fileIdx);
      if (job.cancelled()) break;
      if (whole) {
        postMessage({ id, progress: bytesDone / Math.max(totalBytes, 1), file: file.name });
        let bytes;
        const asked = performance.now();
        try {
          bytes = new Uint8Array(await whole);
        } catch (error) {
          bytes = null;
          job.unreadable(fileIdx, reasonOf(error));
        }
        blobMs += performance.now() - asked;
        if (bytes) job.read_whole(fileIdx, bytes);
        bytesDone += file.size;
        postMessage({ id, progress: bytesDone / Math.max(totalBytes, 1), file: file.name });
        continue;
      }
      for (let start = 0; start < file.size; start += CHUNK_BYTES) {
        if (job.cancelled()) break reading;
        let bytes;
        const asked = performance.now();
        try {
          bytes = new Uint8Array(reader.readAsArrayBuffer(file.slice(start, start + CHUNK_BYTES)));
        } catch (error) {
          job.unreadable(fileIdx, reasonOf(error));
          bytesDone += file.size - start;
          break;
        }
        blobMs += performance.now() - asked;
        bytesDone += bytes.length;
        const readOn = job.feed(fileIdx, bytes);
        postMessage({ id, progress: bytesDone / Math.max(totalBytes, 1), file: file.name });
        if (!readOn) {
          bytesDone += file.size - start - bytes.length;
          break;
        }
      }
    }
    const readAt = now();
    if (!job.cancelled()) job.run((step) => postMessage({ id, step }), () => postMessage({ id, calibrated: true }));
    job.finish();
    // Where the job's time went, for bench/drop_costs.mjs: the page's fixed costs apart
    // from the analysis.
    postMessage({ id, done: true, timing: { startAt, blobMs, readAt, analysedAt: now() } });
  } catch (error) {
    // A trap (a bug): the job is lost; the page says so. (A file that cannot be read is
    // the job's error for that file, `job.unreadable`.)
    postMessage({ id, failed: `${error}` });
  }
}
