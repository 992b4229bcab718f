"""Helper of bench/magfit.sh (not run on its own).

  magfit_report.py split PEER_DIR LOG OUT.json
      The time at which compass-pdr's held-back second half starts, per compass: its
      samples are those paired with an ATT sample within 0.1 s (as compass-pdr pairs
      them, src/calibration/autopilot/samples.rs), split at half their number; the time
      is that of the first sample of the second half (the median MAG time). The log is
      read by the scorer's own reader (score.py's load), so the times are the scorer's.

  magfit_report.py report RESULTS_DIR NAME...
      The Markdown section of docs/ACCURACY.md from the raw results of each log NAME,
      and RESULTS_DIR/summary.json with every figure it prints.
"""
import json
import os
import re
import sys

SETS = ["in force", "MAGFit default", "MAGFit best", "compass-pdr"]
ATTITUDE_GAP_S = 0.1


def split(peer_dir, log, out):
    sys.path.insert(0, peer_dir)
    saved, sys.argv = sys.argv, [sys.argv[0]]   # score.py reads its flags at import
    import numpy as np
    import score
    sys.argv = saved
    data = score.load(log)
    att_t = data["att"][:, 0]
    result = {}
    for i, mag in sorted(data["mags"].items()):
        t = mag[:, 0]
        k = np.searchsorted(att_t, t)
        k0 = np.clip(k - 1, 0, len(att_t) - 1)
        k1 = np.clip(k, 0, len(att_t) - 1)
        near = np.minimum(np.abs(att_t[k0] - t), np.abs(att_t[k1] - t))
        paired = t[near <= ATTITUDE_GAP_S]
        if len(paired) < 2:
            continue
        result[str(i)] = dict(samples=int(len(t)), paired=int(len(paired)),
                              first_half=int(len(paired) // 2),
                              second_half=int(len(paired) - len(paired) // 2),
                              split_s=float(paired[len(paired) // 2]),
                              zero_samples=int(np.sum(np.all(mag[:, 1:4] == 0, axis=1))),
                              use=data["parm"].get(score.names(i)["scale"].replace("SCALE", "USE")),
                              mot_in_force=[data["parm"].get(k, 0.0) for k in score.names(i)["mot"]],
                              motct_in_force=data["parm"].get("COMPASS_MOTCT"),
                              log_start_s=float(t[0]), log_end_s=float(t[-1]))
    json.dump(result, open(out, "w"), indent=1)


def load_json(path):
    try:
        return json.load(open(path))
    except (OSError, ValueError):
        return None


def read_text(path):
    try:
        return open(path).read()
    except OSError:
        return ""


def cell(row):
    return "%.1f mG / %.2f° / %.2f %%" % (row["vec_rms"], row["hdg_rms"], row["spread"])


def param_lines(path):
    """The parameter names a .param file sets (comments and blank lines skipped)."""
    names = []
    for line in read_text(path).splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            names.append(re.split(r"[,\s]", line, 1)[0])
    return names


def compass_suffix(i):
    return "" if i == 0 else str(i + 1)


def lines_for_compass(names, i):
    s = compass_suffix(i)
    pattern = re.compile(r"^COMPASS_(OFS|DIA|ODI|MOT)%s_[XYZ]$|^COMPASS_(SCALE|ORIENT)%s$" % (s, s))
    return [n for n in names if pattern.match(n)]


def report(results, names):
    summary = {}
    out = []
    for name in names:
        base = os.path.join(results, name)
        meta = load_json(base + ".meta.json") or {}
        cpdr = load_json(base + ".compass-pdr.json")
        cpdr_rc = int(read_text(base + ".compass-pdr.rc").strip() or -1)
        cpdr_param = base + ".compass-pdr.param"
        cpdr_written_file = os.path.exists(cpdr_param)
        file_names = param_lines(cpdr_param) if cpdr_written_file else []
        magfit = load_json(base + ".magfit.json")
        magfit_default = os.path.exists(base + ".magfit.MAGFit.param")
        best_choice = load_json(base + ".magfit-best.choice.json") or {}
        splits = load_json(base + ".split.json") or {}
        whole = load_json(base + ".score-whole.json")
        halves = {}
        for i, s in splits.items():
            halves[i] = load_json(base + ".score-half-%s.json" % i)

        out.append("### `%s`" % meta.get("log", name))
        out.append("")
        # compass-pdr
        status = {}
        if cpdr and cpdr.get("autopilot"):
            for c in cpdr["autopilot"]["compasses"]:
                i = str(c["instance"])
                written = c.get("kept_because") is None and c.get("model") is not None
                lines = lines_for_compass(file_names, c["instance"])
                status[i] = dict(written=written, model=c.get("model"), kept_because=c.get("kept_because"),
                                 lines_in_file=len(lines), source=c.get("source"),
                                 check=c.get("check"))
        written_n = sum(1 for s in status.values() if s["written"])
        if cpdr_rc == 0:
            what = "exit 0, %s written (%d of %d compasses)" % (os.path.basename(cpdr_param), written_n, len(status))
        else:
            said = read_text(base + ".compass-pdr.txt").strip()
            said = said[said.find("no autopilot parameters"):].split(":")[0] if "no autopilot parameters" in said else "see %s.compass-pdr.txt" % name
            what = ("exit %d, no file written (\"%s\"): every compass keeps the parameters in force"
                    % (cpdr_rc, said))
        out.append("- compass-pdr `calibrate --param-out`: " + what + ".")
        for i, s in sorted(status.items()):
            if s["written"]:
                desc = "written (%s), %d lines in the file" % (s["model"], s["lines_in_file"])
            else:
                desc = "kept: %s; %d lines for it in the file" % (s["kept_because"], s["lines_in_file"])
            out.append("  - compass %d (%s): %s" % (int(i) + 1, s["source"], desc))
        file_motct = None
        for line in read_text(cpdr_param).splitlines():
            if line.startswith("COMPASS_MOTCT"):
                file_motct = float(re.split(r"[,\s]+", line.strip())[1])
        for i, s in sorted(status.items()):
            sp = splits.get(i, {})
            if (not s["written"] and file_motct is not None and sp.get("motct_in_force") != file_motct
                    and any(v != 0 for v in sp.get("mot_in_force", []))):
                out.append("  - **compass %d is kept, but the file sets COMPASS_MOTCT %g (in force %s) while its COMPASS_MOT in force is not zero**: the autopilot would not apply it as in force"
                           % (int(i) + 1, file_motct, sp.get("motct_in_force")))
        mismatch = [i for i, s in status.items() if s["written"] != (s["lines_in_file"] > 0)]
        if mismatch:
            out.append("  - **the file does not match the status** for compass(es) %s" % ", ".join(str(int(i) + 1) for i in mismatch))
        # MAGFit
        first_try = read_text(base + ".magfit-with-source.stderr").strip().splitlines()
        if first_try:
            out.append("- MAGFit with `--adapter --source \"ATTITUDEEKF 2 IMU 1\"`: saved nothing, `run_magfit.js` stopped with `%s`; run again with `--adapter` only:" % first_try[0])
        if magfit is None:
            out.append("- MAGFit: `run_magfit.js` wrote no JSON (see %s.magfit.stderr)." % name)
        else:
            page = magfit.get("page") or {}
            if not page.get("compasses"):
                out.append("- MAGFit: no fit; the page said: %s." % "; ".join(repr(d) for d in magfit.get("dialogs", [])))
            else:
                saved = [d for d in magfit.get("dialogs", []) if d.startswith("Saved:")]
                saved_text = saved[0].replace("Saved:", "").replace("\n\t", "; ").strip().strip(";").strip() if saved else "nothing saved"
                other = [d.splitlines()[0] for d in magfit.get("dialogs", []) if not d.startswith("Saved:")]
                ef = page.get("earth_field") or {}
                out.append("- MAGFit: attitude source %s%s, %.1f s of work; default selection saved: %s. Best valid fit per compass by MAGFit's own error: %s. Its field: declination %.2f°, inclination %.2f°, %.1f mG. Its dialogs besides: %s."
                           % (page.get("source"), " (picked with `--source`)" if magfit.get("user_actions") else "",
                              magfit.get("seconds", float("nan")), saved_text,
                              "; ".join("compass %d: %s" % (int(k) + 1, v) for k, v in sorted(best_choice.items())) or "none",
                              ef.get("declination", float("nan")), ef.get("inclination", float("nan")),
                              1000 * ef.get("intensity", float("nan")),
                              "; ".join(repr(o) for o in other) or "none"))
        if whole is None:
            out.append("- score.py: no result (see %s.score-whole.txt)." % name)
            out.append("")
            continue
        w = whole["wmm"]
        out.append("- score.py's field: %s (%.3f), declination %.2f°, inclination %.2f°, %.1f mG (%s); AHRS_TRIM added (%.4f, %.4f) rad."
                   % (w["model"], w["year"], w["declination"], w["inclination"], w["intensity_mG"], w["pos_src"],
                      whole["trim"][0], whole["trim"][1]))
        orient = []
        log_summary = dict(log=meta.get("log", name), compass_pdr_rc=cpdr_rc, compasses={})
        out.append("")
        out.append("| compass | part (samples scored) | in force | MAGFit default | MAGFit best | compass-pdr |")
        out.append("|---|---|---|---|---|---|")
        for i, C in sorted(whole["compasses"].items(), key=lambda kv: int(kv[0])):
            s = status.get(i)
            label = "%d" % (int(i) + 1)
            sp = splits.get(i, {})
            if s and sp.get("use") is not None:
                label += " (%s, COMPASS_USE%s %g)" % (s["source"], compass_suffix(int(i)), sp["use"])
                s = dict(s, source=None)
            if s:
                label += "%s: compass-pdr %s" % (" (%s)" % s["source"] if s["source"] else "",
                                                 ("**written** (%s)" % s["model"]) if s["written"] else "**kept**")
                s = status.get(i)
            if sp.get("zero_samples"):
                label += "; %d samples read (0, 0, 0)" % sp["zero_samples"]
            parts = [("whole log", C)]
            H = halves.get(i)
            if H is not None and i in H["compasses"]:
                parts.append(("second half, t ≥ %.3f s" % splits[i]["split_s"], H["compasses"][i]))
            log_summary["compasses"][i] = dict(status=s, parts={})
            for k, (part, D) in enumerate(parts):
                rows = D["rows"]
                cells = []
                figures = {}
                for name_set in SETS:
                    r = rows.get(name_set)
                    if name_set == "compass-pdr" and s and not s["written"] and s["lines_in_file"] == 0:
                        r = rows["in force"]
                        cells.append(cell(r) + " (kept: in force)")
                    elif r is None:
                        if name_set.startswith("MAGFit") and not magfit_default:
                            cells.append("— (no MAGFit fit)")
                        elif name_set == "compass-pdr" and not cpdr_written_file:
                            cells.append(cell(rows["in force"]) + " (kept: in force)")
                            r = rows["in force"]
                        else:
                            cells.append("— (no parameters for it)")
                    else:
                        flag = " ORIENT changed" if r.get("orient_changed") else ""
                        if flag:
                            orient.append((label, name_set))
                        cells.append(cell(r) + flag)
                    figures[name_set] = r
                log_summary["compasses"][i]["parts"][part] = dict(used=D["used"], rows=figures)
                out.append("| %s | %s (%d) | %s |" % (label if k == 0 else "", part, D["used"], " | ".join(cells)))
        out.append("")
        if orient:
            out.append("(ORIENT changed: the file sets another COMPASS_ORIENT than in force, which score.py does not apply.)")
            out.append("")
        cross = []
        for i, s in sorted(status.items()):
            chk = (s.get("check") or {}).get("in_force")
            if chk and i in halves and halves[i] and i in halves[i]["compasses"]:
                r = halves[i]["compasses"][i]["rows"]["in force"]
                cross.append("compass %d: %d samples, %.1f mG in force (score.py: %d samples, %.1f mG)"
                             % (int(i) + 1, chk["n_samples"], chk["vector_rms_mg"], halves[i]["compasses"][i]["used"], r["vec_rms"]))
        if cross:
            out.append("compass-pdr's own held-back half, for comparison with the split used here: " + "; ".join(cross) + ".")
            out.append("")
        summary[name] = log_summary
    json.dump(summary, open(os.path.join(results, "summary.json"), "w"), indent=1)
    print("\n".join(out))


if __name__ == "__main__":
    if sys.argv[1] == "split":
        split(sys.argv[2], sys.argv[3], sys.argv[4])
    elif sys.argv[1] == "report":
        report(sys.argv[2], sys.argv[3:])
    else:
        raise SystemExit(__doc__)
