"""Every `rft-sim` command in README.md and docs/*.md runs as written (the docs cannot drift
from the CLI), and README's set-up commands are the ones `.ci/run` runs.

A command is a line of a ```bash (or sh) block whose first word is `rft-sim` (or a path to
it, `.venv/bin/rft-sim`); `\\` continues a line. Each is parsed by the CLI's own parser, so
an option that does not exist fails here. Then each runs, from the repository's root:

- shortened: a `run` gets `--duration 0.1`, and `--no-bag` unless a later command of its
  page reads its folder (`render`); every `--out` goes into a temporary folder;
- a command whose status is not 0 says so in its comment (`# exit 2`);
- a template is not run: it names a placeholder, a word in capitals (`STUDY.yaml`, `DIR`,
  `HEAD_IP:6379`) or one starting with `my_` (`my_robot.urdf.xacro`); it is parsed only;
- `view` (MuJoCo's interactive viewer) is parsed only: it runs until its window is closed;
- `sweep`, `validate`, `bench` and `warmup` take minutes, and a `--video` run or a `render`
  (which test/test_video.py covers) half a minute: they run in the slow suite
  (`pytest -m slow`); the video ones need offscreen rendering, and are skipped, saying why,
  where there is none;
- a command that differs from one already run only in its `--out` folder runs once.
"""
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from rft_sim_ros.cli import build_parser, joined_values

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / 'README.md'] + sorted((ROOT / 'docs').glob('*.md'))
#: Subcommands whose runs take minutes: the slow suite runs them.
SLOW = {'sweep', 'validate', 'bench', 'warmup'}
#: A placeholder word: capitals (with an extension or a port), or my_...
PLACEHOLDER = re.compile(r'(^|[=/])([A-Z][A-Z0-9_]*[A-Z0-9](\.\w+|:\d+)?|my_\w*)($|[./])')
#: Seconds of sim time a documented run is cut to.
SHORT_S = '0.1'


def logical_lines(block):
    """The lines of a code block, `\\`-continued ones joined."""
    joined, pending = [], ''
    for line in block.splitlines():
        if line.rstrip().endswith('\\'):
            pending += line.rstrip()[:-1] + ' '
            continue
        joined.append(pending + line)
        pending = ''
    return joined + ([pending] if pending else [])


def commands(text):
    """(argument list after `rft-sim`, expected exit status) of every rft-sim command in the
    bash blocks of markdown `text`, in order."""
    found = []
    for block in re.findall(r'^```(?:bash|sh)\n(.*?)^```', text, re.S | re.M):
        for line in logical_lines(block):
            if not re.match(r'\s*\S*rft-sim\s', line):  # (other lines need not be shell)
                continue
            words = shlex.split(line, comments=True)
            if Path(words[0]).name == 'rft-sim':
                status = re.search(r'#\s*exit (\d+)', line)
                found.append((words[1:], int(status.group(1)) if status else 0))
    return found


def is_template(args):
    return any(PLACEHOLDER.search(word) for word in args)


def needs_rendering(args):
    return args[0] == 'render' or '--video' in args or 'video.enabled=true' in args


def page_commands():
    """pytest params of every command, by page, with the commands of its page (a command
    already listed, on this page or another, once)."""
    params, seen = [], set()
    for page in PAGES:
        listed = commands(page.read_text())
        for index, (args, status) in enumerate(listed):
            same = tuple('OUT' if i and args[i - 1] == '--out' else word  # (any folder)
                         for i, word in enumerate(args))
            if (same, status) in seen:
                continue
            seen.add((same, status))
            name = f'{page.relative_to(ROOT)}:{" ".join(args)}'
            marks = [pytest.mark.slow] if args[0] in SLOW or needs_rendering(args) else []
            params.append(pytest.param(listed, index, id=name, marks=marks))
    return params


PARAMS = page_commands()


def runs(param):
    """Whether the command of a PARAMS entry is run (not a template, not the viewer)."""
    listed, index = param.values
    args = listed[index][0]
    return not is_template(args) and args[0] != 'view'


RUNNABLE = [param for param in PARAMS if runs(param)]


def test_the_docs_have_commands_to_run():
    """(The blocks were found: a change of the fences would silently drop them.)"""
    assert len(PARAMS) > 25
    assert len(RUNNABLE) > 15


@pytest.mark.parametrize('listed, index', PARAMS)
def test_a_documented_command_parses(listed, index):
    args, _ = listed[index]
    parser = build_parser()
    try:
        parser.parse_args(joined_values(parser, args))
    except SystemExit as exit_:
        pytest.fail(f'rft-sim {" ".join(args)}: the CLI refuses it (exit {exit_.code})')


def prepared(args, later, out_root):
    """`args` as the test runs it: outputs under out_root, a run shortened (`--no-bag` unless
    one of the `later` commands reads its folder). Returns (args, its output folder)."""
    args, out = list(args), None
    if '--out' in args:
        at = args.index('--out') + 1
        out = args[at]
        args[at] = str(out_root / out)
    if args[0] == 'run':
        if out is None:
            out = f'run-{abs(hash(tuple(args))) % 10**6}'
            args += ['--out', str(out_root / out)]
        args += ['--duration', SHORT_S]
        if not any(out in words for words, _ in later):
            args.append('--no-bag')
    if args[0] == 'render':  # its run's folder is the first argument
        args[1] = str(out_root / args[1])
    return args


def run_cli(args, status):
    """Run `rft-sim args` from the repository's root; a failure message, or None."""
    done = subprocess.run([sys.executable, '-m', 'rft_sim_ros', *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=900,
                          stdin=subprocess.DEVNULL)
    if done.returncode != status:
        return (f'rft-sim {" ".join(args)}: exit {done.returncode}, the docs say {status}\n'
                f'{done.stderr[-2000:]}')
    return None


@pytest.mark.parametrize('listed, index', RUNNABLE)
def test_a_documented_command_runs(listed, index, tmp_path):
    args, status = listed[index]
    if needs_rendering(args):
        from rft_sim_ros.render.gl import offscreen_problem
        pytest.importorskip('av')
        problem = offscreen_problem()
        if problem:
            pytest.skip(problem)
    if args[0] == 'render':  # the run it renders first, as the page has it
        producer = [i for i, (words, _) in enumerate(listed[:index]) if words[0] == 'run'
                    and '--out' in words and words[words.index('--out') + 1] == args[1]]
        assert producer, f'rft-sim {" ".join(args)}: no run before it writes {args[1]}'
        words, _ = listed[producer[-1]]
        failure = run_cli(prepared(words, listed[producer[-1] + 1:], tmp_path), 0)
        assert failure is None, failure
    failure = run_cli(prepared(args, listed[index + 1:], tmp_path), status)
    assert failure is None, failure


def test_a_command_that_fails_fails_the_test(tmp_path):
    """The runner reports what the docs get wrong: an unknown scene, a wrong status."""
    listed = commands('```bash\nrft-sim run no_such_scene --out runs/x\n'
                      'rft-sim scenes plate_drop   # exit 2\n```\n')
    assert [args for args, _ in listed] == [['run', 'no_such_scene', '--out', 'runs/x'],
                                            ['scenes', 'plate_drop']]
    assert run_cli(prepared(listed[0][0], [], tmp_path), listed[0][1]) is not None
    assert run_cli(listed[1][0], listed[1][1]) is not None  # it exits 0, not 2
    with pytest.raises(SystemExit):
        build_parser().parse_args(['run', 'plate_drop', '--no-such-option'])


def test_templates_are_recognised_and_real_commands_are_not():
    assert is_template(['sweep', 'STUDY.yaml', '--out', 'DIR'])
    assert is_template(['run', 'my_robot.urdf.xacro'])
    assert is_template(['sweep', 'x.yaml', '--ray', 'HEAD_IP:6379'])
    assert not is_template(['run', 'hexapod', '--set', 'video.camera=fixed', '--out', 'runs/h'])
    assert not is_template(['run', 'quadruped', '--commands', 'docs/examples/knees.csv'])


def test_readme_gives_the_commands_ci_runs():
    """README's set-up: the install command, then the test command; `.ci/run` runs both."""
    readme = (ROOT / 'README.md').read_text()
    setup = readme[readme.index('## Set up'):readme.index('\n## ', readme.index('## Set up') + 1)]
    blocks = re.findall(r'^```bash\n(.*?)^```', setup, re.S | re.M)
    install, test = (block.strip() for block in blocks[:2])
    ci = (ROOT / '.ci' / 'run').read_text().splitlines()
    assert install in ci and test in ci, (install, test)


def broken_links(page, text):
    """The relative link targets of markdown `text` (a file at `page`) that name no file."""
    targets = re.findall(r'\]\(([^)#\s]+)(?:#[^)]*)?\)', text)
    return [target for target in targets if '://' not in target
            and not (page.parent / target).exists()]


def test_every_link_of_readme_and_docs_names_a_file():
    assert broken_links(ROOT / 'README.md', '[a](docs/none.md) [b](docs/README.md#x)') == [
        'docs/none.md']
    assert {page.name: broken_links(page, page.read_text()) for page in PAGES} == {
        page.name: [] for page in PAGES}
