"""The HTML pages of a grading: links that resolve, counts, escaping, well-formed tags."""

from html import escape
from html.parser import HTMLParser
import os
from pathlib import Path

import pytest

from sim_bridge.grading.html_report import linked_files, write_class_index, write_runs_page

VOID = {'meta', 'img', 'br', 'hr', 'link', 'input'}
SCRIPT = '<script>alert(1)</script>'


class Page(HTMLParser):
    """A parsed page: its text, ids, tags seen, table rows and whether tags nest properly."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.open, self.errors, self.tags, self.ids = [], [], [], set()
        self.rows, self.text, self.cell = [], [], None
        self.feed(path.read_text(encoding='utf-8'))
        self.close()

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append(tag)
        if 'id' in attrs:
            self.ids.add(attrs['id'])
        if tag == 'tr':
            self.rows.append([])
        if tag in ('td', 'th'):
            self.cell = ['', attrs.get('class')]
            self.rows[-1].append(self.cell)
        if tag not in VOID:
            self.open.append(tag)

    def handle_endtag(self, tag):
        if tag in ('td', 'th'):
            self.cell = None
        if not self.open or self.open.pop() != tag:
            self.errors.append(tag)

    def handle_data(self, data):
        self.text.append(data)
        if self.cell is not None:
            self.cell[0] += data

    def row(self, first_cell):
        return next(row for row in self.rows if row[0][0] == first_cell)


def assert_well_formed_and_linked(path):
    page = Page(path)
    assert page.errors == [] and page.open == []
    assert page.tags.count('table') >= 1
    for target in linked_files(path):
        assert target.exists(), target
    return page


def make_run(out_dir, scenario='wall', seed=1, *, passed=True, error=None, traceback=None,
             criteria=None, node_errors=(), log=None, files=()):
    out_dir = Path(out_dir)
    for name in files:
        target = out_dir / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if name.endswith('/'):
            target.mkdir(exist_ok=True)
        else:
            target.write_bytes(b'x')
    if criteria is None:
        criteria = [{'criterion': 'laps >= 1', 'passed': passed, 'value': 1 if passed else 0,
                     'shown': '1' if passed else '0'}]
    run = {'run': f'{scenario}/seed_{seed}', 'scenario': scenario, 'file': f'{scenario}.yaml',
           'world': 'box', 'nodes': ['wall_follow'], 'seed': seed, 'duration_s': 30.0,
           'params': {'wall_follow': {'side': 'left'}}, 'start': 'mirrored', 'passed': passed,
           'error': error, 'traceback': traceback, 'criteria': criteria,
           'out_dir': str(out_dir), 'wall_time_s': 2.5,
           'metrics': None if error else {'node_errors': list(node_errors)}}
    if log is not None:
        run['log'] = str(log)
    return run


@pytest.fixture
def runs(tmp_path):
    grade = tmp_path / 'out' / 'grade'
    log = grade / 'wall' / 'seed_1.log'
    log.parent.mkdir(parents=True)
    log.write_text('stdout\n')
    runs = [
        make_run(grade / 'wall' / 'seed_1', files=['trajectory.png', 'metrics.json', 'run/'],
                 log=log),
        make_run(grade / 'wall' / 'seed_2', seed=2, passed=False, files=['metrics.json'],
                 node_errors=[{'node': 'wall_follow', 'error': 'ZeroDivisionError',
                               'traceback': f'Traceback: in on_scan {SCRIPT}'},
                              {'node': 'wall_follow', 'error': 'second'}]),
        make_run(grade / 'wall' / 'seed_3', seed=3, passed=False, criteria=[],
                 error=f'exit status 3 {SCRIPT}', traceback=f'Traceback {SCRIPT}',
                 log=grade / 'missing.log'),
    ]
    runs[2]['params'] = {'wall_follow': {'side': SCRIPT}}
    return runs


def test_runs_page_links_only_existing_files_relative_to_the_page(tmp_path, runs):
    page = write_runs_page(tmp_path / 'site' / 'ana' / 'report.html', 'Ana', runs,
                           up=tmp_path / 'site' / 'index.html')
    (tmp_path / 'site' / 'index.html').write_text('<html></html>')
    assert_well_formed_and_linked(page)
    linked = {path.resolve() for path in linked_files(page)}
    seed_1 = Path(runs[0]['out_dir']).resolve()
    assert linked == {seed_1 / 'trajectory.png', seed_1 / 'metrics.json', seed_1 / 'run',
                      seed_1.parent / 'seed_1.log', (tmp_path / 'site' / 'index.html'),
                      Path(runs[1]['out_dir']).resolve() / 'metrics.json'}
    assert '"../../out/grade/wall/seed_1/trajectory.png"' in page.read_text()


def test_missing_plot_says_so_and_is_not_linked(tmp_path, runs):
    page = write_runs_page(tmp_path / 'report.html', 'batch', runs)
    text = page.read_text()
    assert text.count('<img') == 1
    assert text.count('no plot') == 2
    assert not any(path.name == 'trajectory.png' and 'seed_2' in str(path)
                   for path in linked_files(page))


def test_relative_out_dirs_resolve_from_the_current_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run = make_run(Path('grade') / 'wall' / 'seed_1', files=['trajectory.png', 'run/'])
    page = write_runs_page(Path('pages') / 'deep' / 'report.html', 'relative', [run])
    files = linked_files(page)
    assert [path.name for path in files] == ['trajectory.png', 'run']
    assert all(path.exists() for path in files)
    assert '"../../grade/wall/seed_1/run/"' in page.read_text()


def test_runs_page_summary_table_and_escaping(tmp_path, runs):
    page = assert_well_formed_and_linked(write_runs_page(tmp_path / 'r.html', 'A<b>', runs))
    text = (tmp_path / 'r.html').read_text()
    assert '1 of 3 runs passed' in ''.join(page.text)
    assert 'script' not in page.tags and 'b' not in page.tags
    assert '&lt;script&gt;alert(1)&lt;/script&gt;' in text and SCRIPT not in text
    header, *rows = page.rows[:6]
    assert [cell[0] for cell in header] == ['run', 'criterion', 'measured', 'result']
    assert [(row[0][0], row[1][0], row[3]) for row in rows] == [
        ('wall/seed_1', 'laps >= 1', ['pass', 'pass']),
        ('wall/seed_2', 'node error: wall_follow: ZeroDivisionError', ['FAIL', 'fail']),
        ('', 'node error: wall_follow: second', ['FAIL', 'fail']),
        ('', 'laps >= 1', ['FAIL', 'fail']),
        ('wall/seed_3', f'error: exit status 3 {SCRIPT}', ['FAIL', 'fail']),
    ]
    assert {'run-0', 'run-1', 'run-2'} <= page.ids
    assert text.count('<pre>') == 4  # two node errors, one with a traceback; the run's


def test_class_index_counts_per_scenario_and_in_total(tmp_path):
    pages = {name: tmp_path / name / 'report.html' for name in ('bo', 'al', SCRIPT)}
    students = {
        'bo': [make_run(tmp_path / 'b1', 'wall'), make_run(tmp_path / 'b2', 'wall', 2),
               make_run(tmp_path / 'b3', 'wall', 3, passed=False),
               make_run(tmp_path / 'b4', 'lap')],
        'al': [make_run(tmp_path / 'a1', 'wall', passed=False, error='not submitted')],
        SCRIPT: [],
    }
    for name in ('bo', 'al'):
        write_runs_page(pages[name], name, students[name], up=tmp_path / 'index.html')
    index = write_class_index(tmp_path / 'index.html', 'class', students, ['wall', 'lap'],
                              pages)
    page = assert_well_formed_and_linked(index)
    for name in ('bo', 'al'):
        assert_well_formed_and_linked(pages[name])
    assert [row[0][0] for row in page.rows] == ['student', SCRIPT, 'al', 'bo']
    # Why runs failed, at a glance: the worst reason of the cell's failed runs.
    assert page.row('bo')[1:] == [['2/3criteria failed', 'some'], ['1/1', 'pass'],
                                  ['3/4criteria failed', 'some']]
    assert page.row('al')[1:] == [['0/1not submitted', 'fail'], ['\u2014', None],
                                  ['0/1not submitted', 'fail']]
    assert 'not submitted: ' in ''.join(page.text)  # the legend
    assert page.row(SCRIPT)[1:] == [['\u2014', None]] * 3
    assert sorted(path.name for path in linked_files(index)) == ['report.html'] * 2
    assert '3 students, 5 runs, 3 passed (60 %)' in ''.join(page.text)
    assert 'script' not in page.tags


def test_linked_files_rejects_links_that_leave_the_folder(tmp_path):
    page = tmp_path / 'p.html'
    page.write_text('<a href="#top">top</a><img src="a%20b.png"><a href="/etc/passwd">x</a>')
    with pytest.raises(ValueError, match='/etc/passwd'):
        linked_files(page)
    page.write_text('<a href="#top">top</a><img src="a%20b.png">')
    assert linked_files(page) == [tmp_path / 'a b.png']


def test_texts_that_are_not_utf8_and_files_named_in_bytes_are_shown_and_linked(tmp_path):
    name, map_name = os.fsdecode(b'Jos\xe9'), os.fsdecode(b'caf\xe9.yaml')
    run = make_run(tmp_path / name / 'wall' / 'seed_1', passed=False, files=['trajectory.png'],
                   error=f'cannot open map {map_name}')
    page = write_runs_page(tmp_path / name / 'report.html', f'Grading report: {name}', [run])
    text = page.read_text(encoding='utf-8')
    assert 'cannot open map caf\\xe9.yaml' in text and 'Grading report: Jos\\xe9' in text
    assert linked_files(page) == [tmp_path / name / 'wall' / 'seed_1' / 'trajectory.png']
    assert_well_formed_and_linked(page)


def test_run_paths_are_relative_to_the_root_given(tmp_path):
    out = tmp_path / 'out'
    make_run(out / 'ana' / 'wall' / 'seed_1', files=['trajectory.png'])
    run = make_run('ana/wall/seed_1')
    page = write_runs_page(out / 'ana' / 'report.html', 'ana', [run], root=out)
    assert linked_files(page) == [out / 'ana' / 'wall' / 'seed_1' / 'trajectory.png']


def test_warnings_long_lines_and_measured_values_read_well(tmp_path):
    criteria = [{'criterion': 'min_clearance_m >= 0', 'passed': True, 'value': 2.873e-09,
                 'shown': '2.873e-09'}]
    run = make_run(tmp_path / 'seed_1', criteria=criteria)
    run['metrics']['warnings'] = ['a thread kept the run alive: Thread-1 (spin)']
    page = Page(write_runs_page(tmp_path / 'report.html', 'batch', [run]))
    assert [[cell[0] for cell in row] for row in page.rows[1:2]] == [
        ['wall/seed_1', 'min_clearance_m >= 0', '0.000 m', 'pass']]
    text = (tmp_path / 'report.html').read_text()
    assert '<li>a thread kept the run alive: Thread-1 (spin)</li>' in text


def test_a_warning_repeated_in_many_runs_is_listed_once_with_its_count(tmp_path):
    ignored = "no node declared parameter 'side' (given for every node, /**); it was ignored"
    runs = []
    for seed in range(48):
        run = make_run(tmp_path / f'seed_{seed}')
        run['metrics']['warnings'] = [ignored, ignored, ignored]
        runs.append(run)
    text = write_runs_page(tmp_path / 'report.html', 'ana', runs).read_text()
    head = text[:text.index('<section')]
    assert head.count(escape(ignored)) == 1
    assert f'<li>{escape(ignored)} <span class="why">(48 runs)</span></li>' in head
    assert 'white-space: pre-wrap' in text and 'overflow-wrap: anywhere' in text
