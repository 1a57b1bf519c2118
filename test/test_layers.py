"""The package's imports point one way: no module imports, however indirectly, a module that
imports it back (a circle), nor does any of the package's parts (its subpackages and
top-level modules: docs/code.md's layers), and only `rft_sim_ros/ros/` imports rclpy.

The graph is read from the sources (every `import` statement, at top level or inside a
function: a function-level import is still a dependency, only a later one), not by importing."""
import ast
import importlib.util
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / 'rft_sim_ros'


def package_modules():
    """{dotted name: source path} of every module of the package (a package by its
    __init__.py)."""
    modules = {}
    for path in PACKAGE.rglob('*.py'):
        parts = path.relative_to(PACKAGE.parent).with_suffix('').parts
        name = '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)
        modules[name] = path
    return modules


def imported_names(name, path, modules):
    """Dotted names module `name` (source `path`) imports anywhere in its source: for
    `from a import b`, `a.b` where that is a module of `modules`, else `a`."""
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    for node in ast.walk(ast.parse(path.read_bytes())):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name('.' * node.level + (node.module or ''), package)
            for alias in node.names:
                yield f'{base}.{alias.name}' if f'{base}.{alias.name}' in modules else base


def import_graph():
    """{module: set of the package's modules importing it runs}: each module it imports and
    that module's enclosing packages (their __init__ runs first), less its own enclosing
    packages (already running when it is imported)."""
    modules = package_modules()
    graph = {}
    for name, path in modules.items():
        edges = set()
        for target in imported_names(name, path, modules):
            parts = target.split('.')
            for end in range(1, len(parts) + 1):
                module = '.'.join(parts[:end])
                if module in modules and not (name == module or name.startswith(module + '.')):
                    edges.add(module)
        graph[name] = edges
    return graph


def circles(graph):
    """The strongly connected components of `graph` with more than one module (Tarjan's
    algorithm, iterative), each a sorted list; and a module importing itself."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1 or node in graph[node]:
                    found.append(sorted(component))
    return found


def part_graph(graph):
    """{part: set of the parts it imports}: `graph` (an `import_graph`) between the package's
    parts, each subpackage or top-level module (rft_sim_ros.X, its modules' edges
    together), with the package's own __init__ and the edges within a part left out."""
    def part(module):
        return '.'.join(module.split('.')[:2])

    parts = {}
    for module, imported in graph.items():
        if module != 'rft_sim_ros':
            parts.setdefault(part(module), set()).update(
                part(target) for target in imported
                if target != 'rft_sim_ros' and part(target) != part(module))
    return parts


def test_the_graph_is_read_from_every_module_and_its_function_level_imports():
    graph = import_graph()
    assert len(graph) > 50
    assert 'rft_sim_ros.sand.implicit_solve' in graph['rft_sim_ros.sand.engine']
    assert 'rft_sim_ros.warmup' in graph['rft_sim_ros.cli']  # imported inside cmd_warmup


def test_circles_are_found_where_there_are_some():
    graph = {'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}, 'e': {'e'}}
    assert sorted(circles(graph)) == [['a', 'b', 'c'], ['e']]
    assert circles({'a': {'b'}, 'b': set()}) == []


def test_no_module_imports_itself_back():
    assert circles(import_graph()) == []


def test_parts_are_joined_with_their_modules_edges():
    graph = {'rft_sim_ros': set(), 'rft_sim_ros.a.x': {'rft_sim_ros.b', 'rft_sim_ros.a.y'},
             'rft_sim_ros.a.y': {'rft_sim_ros'}, 'rft_sim_ros.b': {'rft_sim_ros.c.z'},
             'rft_sim_ros.c.z': {'rft_sim_ros.a.y'}}
    assert part_graph(graph) == {'rft_sim_ros.a': {'rft_sim_ros.b'},
                                 'rft_sim_ros.b': {'rft_sim_ros.c'},
                                 'rft_sim_ros.c': {'rft_sim_ros.a'}}
    assert circles(part_graph(graph)) == [['rft_sim_ros.a', 'rft_sim_ros.b', 'rft_sim_ros.c']]


#: The package's parts by layer, top to bottom (docs/code.md): a part imports only parts of
#: the layers below its own.
LAYERS = (('__main__',), ('cli',), ('bench',), ('validation',), ('study', 'warmup', 'prebuild'),
          ('ros',), ('render',), ('sim',), ('scenes',), ('control', 'robot'), ('sand',),
          ('rft',), ('prebuilt', 'interrupts'),
          ('kernel_names', 'kernel_cache', 'units', 'stamps', 'resources', 'native_threads'))


def test_each_part_imports_only_the_layers_below_its_own():
    """What docs/code.md says of the layers: every part is in one (a new part must be
    placed), and every import between parts points down."""
    rank = {f'rft_sim_ros.{part}': level for level, parts in enumerate(LAYERS)
            for part in parts}
    graph = part_graph(import_graph())
    assert sorted(set(graph) - set(rank)) == []
    upward = sorted((part, target) for part, targets in graph.items() for target in targets
                    if rank[target] <= rank[part])
    assert upward == []


def test_no_part_of_the_package_imports_itself_back():
    """A subpackage's module may import a module of another part that imports a third
    module of the first: no circle of modules, but the parts are no longer layers (docs/code.md
    says which way they point)."""
    parts = part_graph(import_graph())
    assert 'rft_sim_ros.sand' in parts['rft_sim_ros.sim']  # (the parts were read)
    assert circles(parts) == []


def test_the_kernel_cache_bookkeeping_imports_nothing_of_the_package():
    """Every kernel module imports it at its top: it must sit below all of them."""
    assert import_graph()['rft_sim_ros.kernel_cache'] == set()


def test_the_kernels_names_import_nothing_of_the_package():
    """The engine and the gaits name their kernels there (and `prebuilt` loads them by those
    names): it must sit below them."""
    assert import_graph()['rft_sim_ros.kernel_names'] == set()


def test_only_the_ros_package_imports_rclpy():
    modules = package_modules()
    importers = sorted(name for name, path in modules.items()
                       if any(target == 'rclpy' or target.startswith('rclpy.')
                              for target in imported_names(name, path, modules)))
    assert importers, 'the ROS edge imports rclpy somewhere'
    assert [name for name in importers if not name.startswith('rft_sim_ros.ros.')
            and name != 'rft_sim_ros.ros'] == []


#: Lines a module of the package may have at most: past this, split it by concern.
MODULE_LINES = 800


def test_no_module_is_longer_than_its_concern_allows():
    lengths = {name: len(path.read_text().splitlines())
               for name, path in package_modules().items()}
    assert max(lengths.values()) > MODULE_LINES / 4  # (the files were read)
    assert {name: n for name, n in lengths.items() if n > MODULE_LINES} == {}
