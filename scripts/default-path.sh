#!/usr/bin/env bash
# default-path.sh -- the default observer on engineering models, tried as a new user would.
#
#   scripts/default-path.sh [obsynth] [cases.tsv] [model ...]
#
# For every case of cases.tsv (default tests/models/engineering/cases.tsv; the optional
# model names restrict the run to those lines):
#   1. the main job with no options:  obsynth model.sym -o tmp/main
#   2. the design `auto` chose, read from <model>_report.json ("auto" line, "generated")
#   3. obsynth simulate model.sym --method <chosen> --u U --x0 x0 --xhat0 xhat0
#      --t-end T --dt dt, with xhat0 = x0 moved by 20 % of each state's box width,
#      upwards for states 1, 3, 5, ... and downwards for states 2, 4, ...; a move that
#      would leave the box goes the other way (so the initial error is exactly 20 % of the
#      box in every state; a final clamp into the box guards the arithmetic)
#      (DEFAULT_PATH_MIRROR=1: the opposite signs, downwards for states 1, 3, 5, ...)
#   4. the verdict from the CSV, in units of the box: e(t) = max_i |x_i - xhat_i| / width_i;
#      PASS when the run has no NaN, reaches t_end, and max e over the last 10 % of the
#      horizon is below 2 % and below a tenth of e(0).
# The column "open loop" is the same final error for the model simulated from xhat0 with no
# output injection (our own RK4 on the .sym expressions; DEFAULT_PATH_OPEN_LOOP=0 skips it):
# where it is already small, the plant's own stability, not the observer, did the work.
# Each obsynth run gets `timeout 120`. Prints one markdown table row per model and exits 1
# when any case fails (2 on a usage error).
set -u
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(dirname "$here")"
obsynth="${1:-$root/build/synth/obsynth}"
cases="${2:-$root/tests/models/engineering/cases.tsv}"
shift $(( $# > 2 ? 2 : $# ))
if [[ ! -x "$obsynth" || ! -f "$cases" ]]; then
  echo "usage: $0 [obsynth binary] [cases.tsv] [model ...]  (not found: $obsynth or $cases)" >&2
  exit 2
fi
exec python3 - "$obsynth" "$cases" "$@" <<'PY'
import csv, json, math, os, re, shutil, subprocess, sys, tempfile, time

RUN_BUDGET_S = 120          # timeout of each obsynth run
PERTURBATION = 0.20         # initial estimate error, share of the box width
FINAL_SHARE = 0.10          # the final window: last 10 % of the horizon
FINAL_LIMIT = 0.02          # final error below 2 % of the box ...
FINAL_RATIO = 0.10          # ... and below a tenth of the initial error
MIRROR = -1 if os.environ.get('DEFAULT_PATH_MIRROR') == '1' else 1  # the opposite signs
OPEN_LOOP = os.environ.get('DEFAULT_PATH_OPEN_LOOP', '1') != '0'  # the zero-gain baseline column

obsynth, cases_path, only = sys.argv[1], sys.argv[2], set(sys.argv[3:])
models_dir = os.path.dirname(os.path.abspath(cases_path))


def read_cases(path):
    cases = []
    with open(path) as fh:
        for line in fh:
            if not line.strip() or line.startswith('#'):
                continue
            cols = line.rstrip('\n').split('\t')
            if len(cols) != 5:
                sys.exit(f'{path}: expected 5 tab-separated columns: {line!r}')
            cases.append(dict(file=cols[0], u=cols[1].strip(), x0=cols[2].strip(),
                              t_end=cols[3].strip(), dt=cols[4].strip()))
    return cases


def strip_comments(text):
    return '\n'.join(l.split('#', 1)[0] for l in text.splitlines())


def number(text):
    """A bound of the domain line: a decimal, or a simple rational like 1/2."""
    text = text.strip()
    if re.fullmatch(r'[-+0-9.eE/ ()]+', text) is None:
        raise ValueError(f'bound {text!r} is not a number')
    return float(eval(text, {'__builtins__': {}}))


def model_info(path):
    """Model name, state names and the state boxes, read from the .sym text itself."""
    src = strip_comments(open(path).read())
    name = re.search(r'^\s*model\s+(\w+)', src, re.M).group(1)
    states = re.search(r'^\s*states\s+(.*)$', src, re.M).group(1).split()
    domain = re.search(r'^\s*domain\s+(.*)$', src, re.M).group(1)
    boxes = {n: (number(lo), number(hi))
             for n, lo, hi in re.findall(r'(\w+)\s+in\s+\[([^,\]]+),([^\]]+)\]', domain)}
    missing = [s for s in states if s not in boxes]
    if missing:
        raise ValueError(f'no box for {", ".join(missing)} on the domain line')
    return name, states, [boxes[s] for s in states]


def perturbed(x0, boxes):
    xhat = []
    for i, (x, (lo, hi)) in enumerate(zip(x0, boxes)):
        step = PERTURBATION * (hi - lo) * (1 if i % 2 == 0 else -1) * MIRROR
        if not lo <= x + step <= hi:
            step = -step
        xhat.append(min(hi, max(lo, x + step)))
    return xhat


def run(args):
    start = time.monotonic()
    try:
        p = subprocess.run(args, capture_output=True, text=True, timeout=RUN_BUDGET_S)
        return p.returncode, p.stdout, p.stderr, time.monotonic() - start
    except subprocess.TimeoutExpired as e:
        err = e.stderr.decode() if isinstance(e.stderr, bytes) else (e.stderr or '')
        return 124, '', err + f'\ntimeout: killed after {RUN_BUDGET_S} s', time.monotonic() - start


def tail(text, width=110):
    lines = [l.strip() for l in text.strip().splitlines() if l.strip()]
    last = lines[-1] if lines else '(no output)'
    return (last[:width - 3] + '...') if len(last) > width else last


def chosen_design(report):
    auto = report.get('auto') or ''
    m = re.search(r"chose '([\w-]+)'", auto)
    if m:
        return m.group(1)
    generated = report.get('generated') or []
    return generated[0]['method'] if len(generated) == 1 else None


def guarantee_wording(report, method):
    """What the report says about the chosen design's guarantee: a 'guarantee' field when
    the report has one, else the auto line's or the header summary's clause about it."""
    entry = next((g for g in report.get('generated') or [] if g.get('method') == method), {})
    g = entry.get('guarantee')
    if isinstance(g, dict):
        return ': '.join(str(g[k]) for k in ('level', 'line') if k in g)
    if isinstance(g, str):
        return g
    auto = report.get('auto') or ''
    m = re.search(r'guarantee[^;()]*', auto)
    if m:
        return m.group(0).strip()
    design = entry.get('design') or {}
    for key in ('guarantee', 'convergence', 'certificate'):
        if isinstance(design.get(key), str):
            text = design[key].split(';')[0].strip()
            if len(text) > 90 and ':' in text:  # keep the verdict, drop its explanation
                text = text.split(':')[0]
            return (text[:87] + '...') if len(text) > 90 else text
    summary = re.sub(r'`[^`]*`', '', entry.get('summary', ''))
    clauses = [c.strip(' ,.') for c in re.split(r';', summary)
               if re.search(r'guarant|rigorous|sampled|certif', c)]
    clauses = [re.sub(r',\s*\d+ arithmetic operations.*', '', c) for c in clauses]
    return '; '.join(clauses) if clauses else '(none stated)'


MATH = {k: getattr(math, k) for k in
        ('sin', 'cos', 'tan', 'exp', 'log', 'sqrt', 'tanh', 'atan', 'asin', 'acos', 'pi')}


def python_expr(text):
    return compile(text.strip().replace('^', '**'), '<sym>', 'eval')


def field(src, name):
    """The bracketed list `name = [ ... ]` of the .sym text, split at top-level commas."""
    m = re.search(r'^\s*' + name + r'\s*=\s*\[(.*?)\]\s*$', src, re.M | re.S)
    if not m:
        return None
    parts, depth, cur = [], 0, ''
    for ch in m.group(1):
        depth += ch in '(['
        depth -= ch in ')]'
        if ch == ',' and depth == 0:
            parts.append(cur)
            cur = ''
        else:
            cur += ch
    return [python_expr(p) for p in parts + [cur]]


def open_loop_error(path, case, xhat0, states, boxes):
    """Final error (same window and units as the verdict) of the model simulated from xhat0
    WITHOUT output injection (RK4, same dt): what a zero-gain 'observer' achieves. A stable
    plant converges on its own; the observer should do much better than this."""
    src = strip_comments(open(path).read())
    env = dict(MATH)
    pm = re.search(r'^\s*params\s+(.*)$', src, re.M)
    for item in (pm.group(1).split(',') if pm else []):
        name, _, value = item.partition('=')
        if not value.strip():
            return None  # a free parameter: no numeric baseline
        env[name.strip()] = eval(python_expr(value), dict(env))
    im = re.search(r'^\s*inputs\s+(.*)$', src, re.M)
    inputs = im.group(1).split() if im else []
    f = field(src, 'f') or field(src, 'F')
    g = field(src, 'g')
    u = [python_expr(e) for e in case['u'].split(',')] if case['u'] != '-' else []

    def rhs(t, x):
        e = dict(env, t=t)
        e.update(zip(inputs, [eval(c, e) for c in u]))
        e.update(zip(states, x))
        d = [eval(c, e) for c in f]
        return [a + eval(c, e) for a, c in zip(d, g)] if g else d

    def rk4(x, t, dt):
        k1 = rhs(t, x)
        k2 = rhs(t + dt / 2, [a + dt / 2 * b for a, b in zip(x, k1)])
        k3 = rhs(t + dt / 2, [a + dt / 2 * b for a, b in zip(x, k2)])
        k4 = rhs(t + dt, [a + dt * b for a, b in zip(x, k3)])
        return [a + dt / 6 * (p + 2 * q + 2 * r + s) for a, p, q, r, s in zip(x, k1, k2, k3, k4)]

    t_end, dt = float(case['t_end']), float(case['dt'])
    x, xh = [float(v) for v in case['x0'].split(',')], list(xhat0)
    widths = [hi - lo for lo, hi in boxes]
    worst = 0.0
    try:
        for k in range(int(round(t_end / dt))):
            t = k * dt
            x, xh = rk4(x, t, dt), rk4(xh, t, dt)
            if t + dt >= (1 - FINAL_SHARE) * t_end:
                worst = max([worst] + [abs(a - b) / w for a, b, w in zip(x, xh, widths)])
    except (ValueError, OverflowError, ZeroDivisionError):
        return float('inf')  # the model left its domain of definition (sqrt < 0, ...)
    return worst if math.isfinite(worst) else float('inf')


def judge(csv_path, states, boxes, t_end):
    """(e0, e_final, worst state, problem or None) from the simulate CSV."""
    with open(csv_path) as fh:
        rows = list(csv.reader(fh))
    header, data = rows[0], rows[1:]
    col = {n: i for i, n in enumerate(header)}
    widths = [hi - lo for lo, hi in boxes]
    errs, times = [], []
    for r in data:
        t = float(r[0])
        e = []
        for s, w in zip(states, widths):
            x, xh = float(r[col[s]]), float(r[col[s + '_hat']])
            if math.isnan(x) or math.isnan(xh) or math.isinf(xh):
                return None, None, s, f'NaN/inf in {s}_hat at t = {t:g}'
            e.append(abs(x - xh) / w)
        times.append(t)
        errs.append(e)
    if not times or times[-1] < t_end * (1 - 1e-9) - 1e-12:
        return None, None, None, f'CSV ends at t = {times[-1] if times else 0:g} < t_end'
    e0 = max(errs[0])
    window = [e for t, e in zip(times, errs) if t >= (1 - FINAL_SHARE) * t_end]
    worst = max(range(len(states)), key=lambda i: max(e[i] for e in window))
    return e0, max(e[worst] for e in window), states[worst], None


def one_case(case, tmp):
    path = os.path.join(models_dir, case['file'])
    name, states, boxes = model_info(path)
    row = dict(model=case['file'][:-4], main='-', method='-', guarantee='-', e0='-',
               efinal='-', openloop='-', verdict='FAIL', cause='', seconds=0.0)
    xhat0 = perturbed([float(v) for v in case['x0'].split(',')], boxes)
    if OPEN_LOOP:
        ol = open_loop_error(path, case, xhat0, states, boxes)
        row['openloop'] = '-' if ol is None else f'{100 * ol:.3g} %'
    rc, out, err, secs = run([obsynth, path, '-o', os.path.join(tmp, 'main')])
    row['main'], row['seconds'] = str(rc), secs
    report_path = os.path.join(tmp, 'main', f'{name}_report.json')
    if rc != 0 or not os.path.exists(report_path):
        row['cause'] = 'main job: ' + tail(err or out)
        return row
    report = json.load(open(report_path))
    method = chosen_design(report)
    if method is None:
        row['cause'] = 'main job: no design chosen (report "auto": ' + tail(report.get('auto') or '') + ')'
        return row
    row['method'], row['guarantee'] = method, guarantee_wording(report, method)
    args = [obsynth, 'simulate', path, '--method', method, '--x0', case['x0'],
            '--xhat0', ','.join(repr(v) for v in xhat0), '--t-end', case['t_end'],
            '--dt', case['dt'], '-o', os.path.join(tmp, 'sim')]
    if case['u'] != '-':
        args += ['--u', case['u']]
    rc, out, err, secs = run(args)
    row['seconds'] += secs
    csv_path = os.path.join(tmp, 'sim', f'{name}_{method}.csv')
    if rc != 0 or not os.path.exists(csv_path):
        row['cause'] = f'simulate exit {rc}: ' + tail(err or out)
        return row
    e0, ef, worst, problem = judge(csv_path, states, boxes, float(case['t_end']))
    if problem:
        row['cause'] = problem
        return row
    row['e0'], row['efinal'] = f'{100 * e0:.1f} %', f'{100 * ef:.3g} %'
    if ef < FINAL_LIMIT and ef < FINAL_RATIO * e0:
        row['verdict'] = 'PASS'
    else:
        row['cause'] = (f'not converged: {worst} error {100 * ef:.3g} % of its box in the last '
                        f'{100 * FINAL_SHARE:.0f} % of the horizon')
    return row


def main():
    cases = [c for c in read_cases(cases_path) if not only or c['file'][:-4] in only]
    unknown = only - {c['file'][:-4] for c in cases}
    if unknown:
        sys.exit(f'not in {cases_path}: {", ".join(sorted(unknown))}')
    print('| model | main exit | auto chose | guarantee (report) | e(0) | final e | open loop | '
          'verdict | s | cause |')
    print('|---|---|---|---|---|---|---|---|---|---|')
    failures = 0
    for case in cases:
        tmp = tempfile.mkdtemp(prefix='default-path-')
        try:
            row = one_case(case, tmp)
        except Exception as e:  # a broken case file or CSV is a failure of that case
            row = dict(model=case['file'][:-4], main='-', method='-', guarantee='-', e0='-',
                       efinal='-', openloop='-', verdict='FAIL', cause=f'harness: {e}',
                       seconds=0.0)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        failures += row['verdict'] != 'PASS'
        cells = [row['model'], row['main'], row['method'], row['guarantee'].replace('|', '/'),
                 row['e0'], row['efinal'], row['openloop'], row['verdict'], f"{row['seconds']:.0f}",
                 row['cause'].replace('|', '/')]
        print('| ' + ' | '.join(cells) + ' |', flush=True)
    print(f'\n{len(cases) - failures} of {len(cases)} converged on the default path')
    return 1 if failures else 0


sys.exit(main())
PY
