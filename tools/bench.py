#!/usr/bin/env python3
"""Time this project beside compiled Pinocchio in one run and write docs/bench.md and README's table.

    python3 tools/bench.py [--rounds N] [--out docs/bench.md] [--readme README.md] [--no-readme]
    python3 tools/bench.py --readme-only [--out docs/bench.md] [--readme README.md]

1. the pinned venv of tools/robots/setup_venv.sh (Pinocchio 4.1.0 and example-robot-data from
   PyPI; reused when its stamp matches; $CD_ANCHORS_VENV, else .venv-anchors);
2. the C++ timing program ../shared/tools/anchors/cpp/bench_pin.cpp, built once by its build.sh
   against the venv's `pin` wheel (cached in target/anchors; the compile log goes there too);
3. N rounds of: bench_pin (best of 100 windows of ~5 ms per figure), then
   `cargo bench --bench dynamics` (criterion) on the same robots, models and constraint sets
   (benches/robots.rs);
4. the table: for each figure the best over the rounds, our criterion figure being its fastest
   sample (a sample is a window of many calls, like bench_pin's), and ours / Pinocchio;
5. README.md's short figures table, between the lines `<!-- bench:begin -->` and
   `<!-- bench:end -->`, with the date and the machine (CPU model, cores) of the run.

`--readme-only` runs nothing: it parses the figures already in docs/bench.md (date, machine,
rounds, Pinocchio version, the ratios table) and rewrites README.md's table from them.

Only ratios from one run mean anything on a shared machine: both sides see the same load.
Standard library only; opens no network connection besides the venv's pip (first run).
"""
import argparse, datetime, json, os, pathlib, platform, re, subprocess, sys, time

from doc_block import write_block

ROOT = pathlib.Path(__file__).resolve().parent.parent
CPP = ROOT.parent / "shared" / "tools" / "anchors" / "cpp"
VENV = pathlib.Path(os.environ.get("CD_ANCHORS_VENV", ROOT / ".venv-anchors"))
OUT_DIR = ROOT / "target" / "anchors"
ROBOTS = ["ur5", "panda", "solo12", "talos_reduced"]
# (our criterion id, bench_pin column, the Pinocchio call it is compared with)
ALGOS = [
    ("fk", "fk", "forwardKinematics(q, v, a)"),
    ("rnea", "rnea", "rnea"),
    ("crba", "crba", "crba"),
    ("aba", "aba", "aba (LOCAL)"),
    ("constraint_terms", "J+gamma", "constraint Jacobians + γ"),
    ("constrained_dynamics", "cnstrDyn", "constraintDynamics"),
    ("rnea_derivatives", "rneaDeriv", "computeRNEADerivatives"),
    ("aba_derivatives", "abaDeriv", "computeABADerivatives"),
    ("constrained_derivatives", "cd+cdDeriv",
     "constraintDynamics + computeConstraintDynamicsDerivatives"),
]
PIN_NAMES = {"panda7": "panda"}
README = ROOT / "README.md"
BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"
# README's short table: what each robot holds, and the figures it shows (our criterion ids).
ROBOT_LABELS = {
    "ur5": "ur5 (tool0 held)",
    "panda": "panda (fingers locked, TCP held)",
    "solo12": "solo12 (four point feet)",
    "talos_reduced": "talos_reduced (two welded soles)",
}
README_COLS = [
    ("fk", ["fk"]),
    ("rnea", ["rnea"]),
    ("crba", ["crba"]),
    ("aba", ["aba"]),
    ("constrained dynamics", ["constrained_dynamics"]),
    ("rnea / aba / constrained derivatives",
     ["rnea_derivatives", "aba_derivatives", "constrained_derivatives"]),
]


def run(cmd, **kw):
    print("+", " ".join(map(str, cmd)), file=sys.stderr, flush=True)
    return subprocess.run(cmd, check=True, **kw)


def robots_dir():
    """Create or reuse the pinned venv; its script prints example-robot-data's robots/ folder."""
    out = run(["bash", str(ROOT / "tools" / "robots" / "setup_venv.sh"), str(VENV)],
              stdout=subprocess.PIPE, text=True).stdout
    m = re.search(r"URDFs in (\S+)", out)
    if not m:
        sys.exit(f"setup_venv.sh printed no robots folder:\n{out}")
    return pathlib.Path(m.group(1))


def build_pin():
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    with open(OUT_DIR / "build.log", "w") as log:
        out = run(["bash", str(CPP / "build.sh"), str(VENV), str(OUT_DIR)],
                  stdout=subprocess.PIPE, stderr=log, text=True).stdout
    return out.strip().splitlines()[-1]


def parse_pin(text):
    """{robot: {column: µs}} from bench_pin's two tables, and the Pinocchio version."""
    version = re.search(r"Pinocchio (\S+),", text).group(1)
    rows, header = {}, None
    for line in text.splitlines():
        cells = line.split()
        if len(cells) > 4 and cells[:4] == ["robot", "nq", "nv", "nc"]:
            header = cells[4:]
        elif header and cells and PIN_NAMES.get(cells[0], cells[0]) in ROBOTS:
            robot = PIN_NAMES.get(cells[0], cells[0])
            vals = rows.setdefault(robot, {"nq": cells[1], "nv": cells[2], "nc": cells[3]})
            for col, x in zip(header, cells[4:4 + len(header)]):
                vals.setdefault(col, float(x))
        elif not cells:
            header = None
    return version, rows


def criterion_us(bench_id):
    """(fastest sample, median) in µs of one criterion id."""
    # criterion writes the id "robot/algo" to the folder "robot_algo"
    base = ROOT / "target" / "criterion" / bench_id.replace("/", "_") / "new"
    s = json.loads((base / "sample.json").read_text())
    best = min(t / n for t, n in zip(s["times"], s["iters"]))
    med = json.loads((base / "estimates.json").read_text())["median"]["point_estimate"]
    return best / 1e3, med / 1e3


def machine():
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def table(pin, ours, version, loads, rounds, pin_text, rustc):
    ncpu = os.cpu_count() or 1
    # The benchmark itself keeps one core busy (a load of 1); beyond that, other work ran.
    loaded = max(loads) > 1.0 + 0.25 * ncpu
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [
        "# Speed against compiled Pinocchio",
        "",
        f"Written by `python3 tools/bench.py` on {now}: {machine()}; {rustc}; Pinocchio {version} "
        "(PyPI `pin` wheel, its compiled `libpinocchio_default`, called from C++ by "
        "`../shared/tools/anchors/cpp/bench_pin.cpp`).",
        "",
        f"Both sides in the same run ({rounds} round(s) of Pinocchio then ours; best per "
        "figure over the rounds). Pinocchio: best of 100 windows of ~5 ms. Ours: criterion's "
        "fastest sample (each a window of many calls); the median is in the last column. "
        "Same URDFs, locked joints and constraint sets; random states drawn from the same "
        "distributions (benches/robots.rs). Ratio = ours / Pinocchio, below 1 means faster.",
        "",
    ]
    if loaded:
        lines += [f"Measured on a loaded {ncpu}-core machine (load average "
                  f"{min(loads):.1f}–{max(loads):.1f}: other work ran at the same time), so "
                  "the absolute times are noisy; the ratios are what this run supports.", ""]
    lines += ["## Ratios", "", "| robot | " + " | ".join(a for a, _, _ in ALGOS) + " |",
              "|---|" + "---|" * len(ALGOS)]
    for r in ROBOTS:
        cells = [f"{ours[r][a][0] / pin[r][c]:.2f}×" for a, c, _ in ALGOS]
        lines.append(f"| {r} | " + " | ".join(cells) + " |")
    lines += ["", "## Times [µs]", "",
              "| robot (nq, nv, rows) | our id | Pinocchio call | ours | Pinocchio | ratio | ours, median |",
              "|---|---|---|---|---|---|---|"]
    for r in ROBOTS:
        p = pin[r]
        for a, c, call in ALGOS:
            best, med = ours[r][a]
            lines.append(f"| {r} ({p['nq']}, {p['nv']}, {p['nc']}) | `{a}` | `{call}` | "
                         f"{best:.3f} | {p[c]:.3f} | {best / p[c]:.2f} | {med:.3f} |")
    lines += [
        "",
        "Notes: Pinocchio's `crba` fills the upper triangle of M only, ours the lower triangle "
        "only (what the factorizations of M read): one triangle each. "
        "`rnea_derivatives` returns M as well (as ∂τ/∂q̈), as Pinocchio's call does. "
        "Contacts: ur5 tool0 and panda panda_hand_tcp points, solo12's four feet (3 rows each, "
        "world axes, as Pinocchio's CONTACT_3D LOCAL_WORLD_ALIGNED); talos_reduced's soles "
        "welded (6 rows each; ours in world axes, Pinocchio's CONTACT_6D in the sole's axes). "
        "Pinocchio's constraintDynamics runs with ProximalSettings(1e-12, μ = 0, 1 iteration); "
        "ours without Baumgarte gains.",
        "",
        "<details><summary>bench_pin output (last round)</summary>",
        "",
        "```",
        pin_text.rstrip(),
        "```",
        "</details>",
        "",
    ]
    return "\n".join(lines)


def parse_bench(text):
    """The figures README's table needs, from a docs/bench.md that table() wrote."""
    head = re.search(r"Written by `python3 tools/bench.py` on (\d{4}-\d\d-\d\d \d\d:\d\d UTC): "
                     r"(.+?), (\d+) cores, ([^;]+); [^;]+; Pinocchio (\S+) ", text)
    rounds = re.search(r"\((\d+) round\(s\)", text)
    if not head or not rounds:
        sys.exit("bench.md: no 'Written by ... on DATE: CPU, N cores, OS; rustc; Pinocchio V' "
                 "line or no round count; regenerate it with python3 tools/bench.py")
    date, cpu, cores, system, version = head.groups()
    ratios, header = {}, None
    for line in text.split("## Ratios", 1)[-1].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("## "):
            break
        if cells[0] == "robot":
            header = cells[1:]
        elif header and cells[0] in ROBOTS:
            ratios[cells[0]] = dict(zip(header, cells[1:]))
    missing = [f"{r}/{a}" for r in ROBOTS for _, ids in README_COLS for a in ids
               if a not in ratios.get(r, {})]
    if missing:
        sys.exit(f"bench.md: its ratios table lacks {', '.join(missing)}")
    loaded = "Measured on a loaded" in text
    return dict(date=date, cpu=cpu, cores=int(cores), system=system, version=version,
                rounds=int(rounds.group(1)), ratios=ratios, loaded=loaded)


def readme_table(fig):
    """README's figures table (Markdown lines) from parse_bench's figures."""
    load = " under load (other work ran: noisy)" if fig["loaded"] else ""
    lines = [
        "<!-- written by python3 tools/bench.py from docs/bench.md: do not edit -->",
        f"Measured {fig['date']} on {fig['cpu']}, {fig['cores']} cores ({fig['system']}){load}; "
        f"compiled Pinocchio {fig['version']}; best per figure over {fig['rounds']} round(s). "
        "Times and medians: [docs/bench.md](docs/bench.md).",
        "",
        "| robot | " + " | ".join(name for name, _ in README_COLS) + " |",
        "|---|" + "---|" * len(README_COLS),
    ]
    for r in ROBOTS:
        cells = [" / ".join(fig["ratios"][r][a] for a in ids) for _, ids in README_COLS]
        lines.append(f"| {ROBOT_LABELS[r]} | " + " | ".join(cells) + " |")
    return lines


def write_readme(path, bench_text):
    """Replace what lies between README's two bench markers; returns the new table."""
    lines = readme_table(parse_bench(bench_text))
    write_block(path, BEGIN, END, "\n".join(lines))
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "bench.md"),
                    help="the full report (read, not written, with --readme-only)")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--readme", default=str(README),
                    help="the file whose table between the bench markers is rewritten")
    ap.add_argument("--no-readme", action="store_true",
                    help="write --out only, leave the README as it is")
    ap.add_argument("--readme-only", action="store_true",
                    help="run no benchmark: rewrite the README table from the figures in --out")
    args = ap.parse_args()
    if args.readme_only:
        print(write_readme(args.readme, pathlib.Path(args.out).read_text()))
        return
    robots = robots_dir()
    bin_path = build_pin()
    env = dict(os.environ, CD_ROBOTS_DIR=str(robots))
    # Build first, and let the build's load fade (the 1-minute load average, at most 3 minutes),
    # so that the load figure reported is the machine's, not our own compiler's.
    run(["cargo", "bench", "--bench", "dynamics", "--no-run"], cwd=ROOT, env=env)
    for _ in range(36):
        if os.getloadavg()[0] <= 1.0:
            break
        time.sleep(5)
    pin, ours, loads, version, pin_text = {}, {}, [os.getloadavg()[0]], "?", ""
    for _ in range(args.rounds):
        pin_text = run([bin_path, str(robots.parent)], stdout=subprocess.PIPE, text=True).stdout
        version, rows = parse_pin(pin_text)
        for r, vals in rows.items():
            for c, x in vals.items():
                cur = pin.setdefault(r, {}).get(c)
                pin[r][c] = x if cur is None or isinstance(x, str) else min(cur, x)
        loads.append(os.getloadavg()[0])
        run(["cargo", "bench", "--bench", "dynamics", "--", "--noplot"], cwd=ROOT, env=env,
            stdout=subprocess.DEVNULL)
        for r in ROBOTS:
            for a, _, _ in ALGOS:
                best, med = criterion_us(f"{r}/{a}")
                prev = ours.setdefault(r, {}).get(a)
                ours[r][a] = (best, med) if prev is None else (min(prev[0], best), min(prev[1], med))
        loads.append(os.getloadavg()[0])
    rustc = run(["rustc", "--version"], stdout=subprocess.PIPE, text=True).stdout.strip()
    text = table(pin, ours, version, loads, args.rounds, pin_text, rustc)
    pathlib.Path(args.out).write_text(text)
    print(text)
    if not args.no_readme:
        write_readme(args.readme, text)


if __name__ == "__main__":
    main()
