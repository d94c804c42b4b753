"""What the documentation tests check, as functions the tests (test_docs.py) and their self-tests
call on the package or on inputs they make up.

- parameters_read(): every private parameter a node or nodelet reads, from the C++ sources:
  calls `FUNC(HANDLE, "name", ...)` (read_param, read_vector3, ... : any call whose first argument
  is a ros::NodeHandle and whose second a string literal, except param_name), and
  `HANDLE.param<T>("name"...)`, `HANDLE.getParam("name"...)`, `HANDLE.hasParam("name")`, ...;
  a handle made as `ros::NodeHandle h(parent, "sub")` reads under "sub/"; a call of a reader
  defined in src/ros/params.cpp that takes only a handle (read_protocol) reads what that
  function reads.
- parameters_documented(): the rows of the `| parameter | type | default | ...` tables of each
  `## node` section of docs/nodes.md.
- compare_parameters(): the differences, one line each, naming the parameter, the node, the
  source line and what to do.
"""
import os
import re
import subprocess

PACKAGE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))

# Which node (a `## name` section of docs/nodes.md) each source file that reads parameters
# belongs to. A nodelet reads its node's parameters. A new file that reads parameters must be
# added here (the test says so).
NODE_SOURCES = {
    "calibration": ["src/ros/calibration_options.cpp", "src/ros/calibration_node.cpp",
                    "src/ros/tumble_calibration_node.cpp",
                    "src/nodes/calibration.cpp", "src/nodelets/calibration_nodelet.cpp"],
    "gimbal_controller": ["src/ros/gimbal_controller_options.cpp",
                          "src/drivers/gimbal_driver_table.cpp", "src/ros/ros_driver_params.cpp",
                          "src/ros/gimbal_controller_node.cpp", "src/nodes/gimbal_controller.cpp"],
    "accelerometer": ["src/ros/accelerometer_node.cpp", "src/ros/accelerometer_serial_lines.cpp",
                      "src/nodes/accelerometer.cpp"],
    "apply_calibration": ["src/ros/apply_calibration_node.cpp", "src/nodes/apply_calibration.cpp",
                          "src/nodelets/apply_calibration_nodelet.cpp"],
    "sim_clock": ["src/ros/sim_clock.cpp", "src/nodes/sim_clock.cpp"],
    "joint_controller_emulator": ["src/ros/joint_controller_emulator.cpp",
                                  "src/nodes/joint_controller_emulator.cpp"],
}
# Python nodes: their private parameters are the literal `rospy.get_param("~name"` calls.
PY_NODE_SOURCES = {"dashboard": ["scripts/dashboard"]}
_PY_PARAM = re.compile(r"rospy\.get_param\(\s*\"~([\w/]+)\"")
# Files that read through drivers::DriverParams (driver_params_in_source).
DRIVER_TABLE_SOURCES = ["src/drivers/gimbal_driver_table.cpp"]
# Files with readers only (no parameter of their own), searched but owned by no node.
HELPER_SOURCES = ["src/ros/params.cpp"]
# Where parameters may be read.
SOURCE_DIRS = ["src/ros", "src/nodes", "src/nodelets", "src/drivers"]

# A handle made from a variable rather than a literal (`ros::NodeHandle dn(pnh, driver)`): the
# placeholder nodes.md writes for it.
PLACEHOLDERS = {"driver": "<driver>", "key": "phases/<p>"}

_HANDLE_DECL = re.compile(r"ros::NodeHandle\s*&?\s+(\w+)\s*(?:\(\s*(\w+)\s*,\s*([^)]*?)\s*\))?")
_HANDLE_EXPR = r"(?:getPrivateNodeHandle\(\)|ros::NodeHandle\(\"~\"\)|\w+)"
_CALL = re.compile(r"\b(\w+)\(\s*(" + _HANDLE_EXPR + r")\s*,\s*\"([^\"]+)\"")
_METHOD = re.compile(r"(" + _HANDLE_EXPR + r")\s*\.\s*(param|getParam|getParamCached|hasParam|"
                     r"searchParam)\s*(?:<[^>]*>)?\(\s*\"([^\"]+)\"")
_READER_DEF = re.compile(r"^[\w:<>]+\s+(\w+)\(const ros::NodeHandle& (\w+)\)\s*\{(.*?)^\}",
                         re.M | re.S)
NOT_READS = {"param_name", "require"}


def _strip_comments(text):
    text = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def handle_readers(params_cpp_text):
    """{function: [names]} for the readers of params.cpp that take only a handle."""
    out = {}
    for m in _READER_DEF.finditer(_strip_comments(params_cpp_text)):
        func, handle, body = m.group(1), m.group(2), m.group(3)
        out[func] = [c.group(3) for c in _CALL.finditer(body)
                     if c.group(2) == handle and c.group(1) not in NOT_READS]
    return out


def reads_in_source(text, readers=None):
    """[(name, line)] of the private parameters one source file reads."""
    text = _strip_comments(text)
    readers = readers or {}
    prefix = {"pnh": "", "pnh_": "", "nh": "", "getPrivateNodeHandle()": "",
              'ros::NodeHandle("~")': ""}
    for m in _HANDLE_DECL.finditer(text):
        name, parent, sub = m.group(1), m.group(2), m.group(3)
        if parent is None:
            prefix.setdefault(name, "")
            continue
        sub = sub.strip()
        if sub.startswith('"'):
            sub = sub.strip('"')
        else:
            sub = PLACEHOLDERS.get(sub, "<" + sub + ">")
        prefix[name] = prefix.get(parent, "") + sub + "/"
    found = []

    def line_of(pos):
        return text.count("\n", 0, pos) + 1

    for m in _CALL.finditer(text):
        func, handle, name = m.groups()
        if handle in prefix and func not in NOT_READS and func not in prefix:
            found.append((prefix[handle] + name, line_of(m.start())))
    for m in _METHOD.finditer(text):
        handle, _, name = m.groups()
        if handle in prefix:
            found.append((prefix[handle] + name, line_of(m.start())))
    for func, names in readers.items():
        for m in re.finditer(r"\b" + func + r"\(\s*(" + _HANDLE_EXPR + r")\s*\)", text):
            if m.group(1) in prefix:
                found += [(prefix[m.group(1)] + n, line_of(m.start())) for n in names]
    return found


# The gimbal driver table reads its rows' parameters through drivers::DriverParams
# (params.get / keys / get_effects) with keys joined from literals and a few variables; each
# variable becomes the placeholder nodes.md writes (an unknown one: not a parameter name).
_DRIVER_KEY = re.compile(r"\bparams\.(?:get|get_effects|keys)\(\s*([^,)]+?)\s*[,)]"
                         r"|\bread_number_or_string\(\s*params\s*,\s*([^,)]+?)\s*,")
_DRIVER_VAR = re.compile(r"const std::string (\w+) = ([^;]+);")
_AXIS_MAP_CALL = re.compile(r"\bread_axis_map\(\s*params\s*,\s*\"(\w+)\"\s*\)")
DRIVER_PLACEHOLDERS = {"driver": "<driver>", "axis": "<A>", '"xyz"[p]': "<p>"}


def _driver_key(expr, variables):
    """The parameter name of a `+`-joined key expression, or None when a part is unknown."""
    out = ""
    for part in (p.strip() for p in expr.split("+")):
        if part in DRIVER_PLACEHOLDERS:
            out += DRIVER_PLACEHOLDERS[part]
        elif part.startswith('"') and part.endswith('"'):
            out += part[1:-1]
        elif part in variables:
            out += variables[part]
        else:
            return None
    return out


def driver_params_in_source(text):
    """[(name, line)] of the driver table's DriverParams reads: a map's entries (`.../hold/<x>`)
    count as the map; an axis map read for a named driver is its one `<driver>/phases/{x,y,z}`."""
    text = _strip_comments(text)
    found = []
    variables = {}
    events = sorted([(m.start(), "var", m) for m in _DRIVER_VAR.finditer(text)] +
                    [(m.start(), "key", m) for m in _DRIVER_KEY.finditer(text)] +
                    [(m.start(), "map", m) for m in _AXIS_MAP_CALL.finditer(text)],
                    key=lambda e: e[0])
    for pos, kind, m in events:
        line = text.count("\n", 0, pos) + 1
        if kind == "var":
            value = _driver_key(m.group(2), variables)
            if value is not None:
                variables[m.group(1)] = value
        elif kind == "map":
            found.append((m.group(1) + "/phases/{x,y,z}", line))
        else:
            name = _driver_key(m.group(1) or m.group(2), variables)
            if name is None:
                continue
            name = re.sub(r"/hold/.*$", "/hold", name)
            found.append((name, line))
    return found


def source_files(package=PACKAGE):
    out = []
    for d in SOURCE_DIRS:
        full = os.path.join(package, d)
        if os.path.isdir(full):
            out += [os.path.join(d, f) for f in sorted(os.listdir(full)) if f.endswith(".cpp")]
    return out


def parameters_read(package=PACKAGE, extra_sources=None):
    """({node: {name: "file:line"}}, [problems]). extra_sources: {path: text} read as if present
    (self-tests)."""
    read = lambda p: open(os.path.join(package, p)).read()  # noqa: E731
    readers = handle_readers(read("src/ros/params.cpp"))
    texts = {p: read(p) for p in source_files(package)}
    texts.update(extra_sources or {})
    owner = {f: node for node, files in NODE_SOURCES.items() for f in files}
    nodes, problems = {n: {} for n in NODE_SOURCES}, []
    for path, text in sorted(texts.items()):
        found = reads_in_source(text, readers)
        if path in DRIVER_TABLE_SOURCES:
            found += driver_params_in_source(text)
        if not found or path in HELPER_SOURCES:
            continue
        if path not in owner:
            problems.append("%s reads parameters (%s) but belongs to no node: add it to "
                            "NODE_SOURCES in test/docs/docs_check.py"
                            % (path, ", ".join(sorted({n for n, _ in found}))))
            continue
        for name, line in found:
            nodes[owner[path]].setdefault(name, "%s:%d" % (path, line))
    for node, files in PY_NODE_SOURCES.items():
        nodes[node] = {}
        for path in files:
            text = read(path)
            for m in _PY_PARAM.finditer(text):
                line = text.count("\n", 0, m.start()) + 1
                nodes[node].setdefault(m.group(1), "%s:%d" % (path, line))
    return nodes, problems


_ROW = re.compile(r"^\|\s*`([^`]+)`\s*\|([^|]*)\|([^|]*)\|")


def parameters_documented(nodes_md_text):
    """{node: {name: (type, default)}} from the parameter tables under each `## node` heading."""
    out, node, in_table = {}, None, False
    for line in nodes_md_text.splitlines():
        if line.startswith("## "):
            node = line[3:].strip().split()[0] if line[3:].strip() else None
            in_table = False
            continue
        if node is None:
            continue
        if line.startswith("| parameter |"):
            in_table = True
            out.setdefault(node, {})
            continue
        if in_table and not line.startswith("|"):
            in_table = False
            continue
        if in_table:
            m = _ROW.match(line)
            if m:
                out[node][m.group(1).lstrip("~")] = (m.group(2).strip(), m.group(3).strip())
    return out


def compare_parameters(read, documented):
    """Lines, one per difference, that say which parameter is missing where."""
    lines = []
    for node in sorted(read):
        doc = documented.get(node, {})
        for name in sorted(read[node]):
            if name not in doc:
                lines.append("docs/nodes.md, section '## %s': parameter `%s` (read at %s) is "
                             "missing: add a row | `%s` | type | default | unit | meaning |"
                             % (node, name, read[node][name], name))
            else:
                typ, default = doc[name]
                if not typ or not default:
                    lines.append("docs/nodes.md, section '## %s': parameter `%s` has no %s"
                                 % (node, name, "type" if not typ else "default"))
        for name in sorted(set(doc) - set(read[node])):
            lines.append("docs/nodes.md, section '## %s': parameter `%s` is listed but the "
                         "code never reads it (remove the row, or it belongs to another node)"
                         % (node, name))
    for node in sorted(set(documented) - set(read)):
        lines.append("docs/nodes.md, section '## %s': a parameter table for a node the test does "
                     "not know (add it to NODE_SOURCES in test/docs/docs_check.py)" % node)
    return lines


# ---- paths outside the package ------------------------------------------------------------

OUTSIDE = [
    (re.compile(r"\.\./shared"), "the shared directory beside the package"),
    (re.compile(r"/work/"), "an absolute path of the development machine"),
    (re.compile(r"DESIGN\.md"), "the shared design file (the package's own is docs/design.md)"),
    (re.compile(r"STYLE\.md"), "the shared style guide"),
    (re.compile(r"(?<![\w.])\.\./\.\./\.\./"), "a relative path that leaves the package"),
]
TEXT_SUFFIXES = (".cpp", ".h", ".hpp", ".py", ".sh", ".md", ".txt", ".yaml", ".yml", ".xml",
                 ".launch", ".test", ".msg", ".srv", ".cfg", ".dot", ".cmake", "")


def package_files(package=PACKAGE):
    try:
        files = subprocess.run(["git", "-C", package, "ls-files"], check=True,
                               capture_output=True, text=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        files = []
        for root, dirs, names in os.walk(package):
            dirs[:] = [d for d in dirs if not d.startswith(".")]
            files += [os.path.relpath(os.path.join(root, n), package) for n in names]
    return [f for f in files if os.path.splitext(f)[1] in TEXT_SUFFIXES
            and not f.startswith("test/data/")]


def outside_references(texts):
    """[(path, line, what)] for {path: text}. The documentation tests name the patterns (and
    feed them to their self-tests): test/docs/ is skipped."""
    out = []
    for path, text in sorted(texts.items()):
        if path.startswith("test/docs/"):
            continue
        for n, line in enumerate(text.splitlines(), 1):
            for pattern, what in OUTSIDE:
                if pattern.search(line):
                    out.append((path, n, what))
    return out


# ---- runnable commands --------------------------------------------------------------------

RUNNABLE_MARK = "<!-- runnable -->"


def runnable_blocks(text):
    """The ```bash blocks that follow the marker line directly: [(first line number, code)]."""
    lines, out, i = text.splitlines(), [], 0
    while i < len(lines):
        if lines[i].strip() == RUNNABLE_MARK:
            j = i + 1
            if j < len(lines) and lines[j].strip() == "```bash":
                k = j + 1
                while k < len(lines) and lines[k].strip() != "```":
                    k += 1
                out.append((j + 2, "\n".join(lines[j + 1:k])))
                i = k
        i += 1
    return out


def markdown_files(package=PACKAGE):
    docs = os.path.join(package, "docs")
    return ["README.md"] + ["docs/" + f for f in sorted(os.listdir(docs)) if f.endswith(".md")]
