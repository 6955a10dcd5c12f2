"""A parameters file and the ROS arguments of a command line (--params-file FILE, -p NAME:=VALUE) read as rcl reads
them, with PyYAML and no ROS package: the sections that apply to the node, nested maps as dotted names, a later value
winning; the names given checked against the schema (`akd_ros.params.schema.check_names`)."""

from __future__ import annotations

import itertools
import re

import yaml

from akd_ros.params.schema import ParameterError, check_names


def read_parameters_file(path: str, node_name: str = "akd_node") -> dict[str, object]:
    """The parameters the ROS parameters file `path` gives the node `node_name`, by dotted name, read as rcl reads
    a --params-file; unknown names refused (`check_names`); raises ParameterError naming the file.

    Its sections apply to the node as rcl applies them: the node's own (``akd_node:``, ``/akd_node:``, or nested
    under its namespace) and the wildcards (``/**:``, ``/*:``, ``/**/akd_node:``), each one's ros__parameters by
    name, nested maps and dotted keys alike (``limits: {max_velocity: 6.0}`` is ``limits.max_velocity``); a later
    section wins over an earlier one for a name both give."""
    sections: dict[str, dict[str, object]] = {}
    _add_file(sections, path)
    return _checked_for(sections, node_name)


def read_arguments(arguments: list[str], node_name: str = "akd_node") -> dict[str, object]:
    """The parameters the ROS arguments of a command line give the node `node_name` (each --params-file FILE and
    -p NAME:=VALUE of its --ros-args, as `read_parameters_file` reads a file), by dotted name; unknown names
    refused; raises ParameterError.

    As rcl merges them: all of them, in order, into one set of sections (-p is ``/**``), a later value of a name
    replacing an earlier one in its section; the sections then apply to the node in the order each first
    appeared."""
    return _checked_for(argument_sections(arguments), node_name)


def argument_sections(arguments: list[str]) -> dict[str, dict[str, object]]:
    """The parameters ROS arguments set, as rcl merges them: by section (a node name or a wildcard, fully
    qualified) in the order each first appears, then by dotted name; ParameterError for a file it cannot read."""
    sections: dict[str, dict[str, object]] = {}
    ros = False
    # Each with the one after it (None after the last): no argument at all is none.
    for argument, following in itertools.pairwise([*arguments, None]):
        if argument in ("--ros-args", "--"):
            ros = argument == "--ros-args"
        elif ros and following is not None and argument in ("-p", "--param"):
            name, _, text = following.partition(":=")
            if name:  # rcl refuses -p without a name
                sections.setdefault("/**", {})[name] = _yaml_value(text)
        elif ros and following is not None and argument == "--params-file":
            _add_file(sections, following)
    return sections


def _checked_for(sections: dict[str, dict[str, object]], node_name: str) -> dict[str, object]:
    """What `sections` give the node `node_name` (a later section wins), its names checked."""
    node = node_name if node_name.startswith("/") else f"/{node_name}"
    named: dict[str, object] = {}
    for section, parameters in sections.items():
        if _applies(section, node):
            named.update(parameters)
    check_names(named)
    return named


def _applies(section: str, node: str) -> bool:
    """Whether the section `section` (a fully qualified node name, where ``*`` is one name and ``**`` any number)
    applies to the node `node` (fully qualified)."""
    tokens = {"**": "(/[^/]+)*", "*": "/[^/]+"}
    return re.fullmatch("".join(tokens.get(t, "/" + re.escape(t)) for t in section[1:].split("/")), node) is not None


def _add_file(sections: dict[str, dict[str, object]], path: str) -> None:
    """Adds the parameters of the parameters file `path` to `sections`; ParameterError naming the file (and the line
    and column of a YAML error)."""
    try:
        with open(path, encoding="utf-8") as stream:
            tree = yaml.safe_load(stream)
    except OSError as e:
        raise ParameterError(f"parameters file {path}: {e.strerror}") from None
    except yaml.MarkedYAMLError as e:
        raise ParameterError(f"parameters file {path}, {_yaml_problem(e)}") from None
    except yaml.YAMLError as e:
        raise ParameterError(f"parameters file {path}: {' '.join(str(e).split())}") from None
    for section, parameters in _sections_of(tree, path):
        sections.setdefault(section, {}).update(parameters)


def _yaml_problem(error: yaml.MarkedYAMLError) -> str:
    """'line L, column C: problem (context, line L, column C)' of a YAML error, on one line."""
    mark = error.problem_mark or error.context_mark
    text = f"line {mark.line + 1}, column {mark.column + 1}: {error.problem or error.context}"
    if error.problem and error.context and error.context_mark:
        text += f" ({error.context}, line {error.context_mark.line + 1}, column {error.context_mark.column + 1})"
    return " ".join(text.split())


def _sections_of(tree: object, path: str, node: tuple[str, ...] = ()) -> list[tuple[str, dict[str, object]]]:
    """(fully qualified node name, its ros__parameters by dotted name) of each section of a parameters file's tree,
    in order; `node` is the names of the maps above `tree`."""
    if tree is None and not node:
        return []  # an empty file
    if not isinstance(tree, dict):
        where = "/".join(node) or "the top level"
        raise ParameterError(
            f"parameters file {path}: {where} must be a map of node names, each with its ros__parameters"
        )
    found = []
    for key, value in tree.items():
        if key == "ros__parameters" and node:
            found.append(("/" + "/".join(n.strip("/") for n in node), _parameters_of(value)))
        else:
            found += _sections_of(value, path, (*node, str(key)))
    return found


def _parameters_of(tree: object, prefix: str = "") -> dict[str, object]:
    """The parameters of a ros__parameters map by dotted name: a nested map's keys joined to its own with '.'."""
    if not isinstance(tree, dict):
        return {prefix: tree} if prefix else {}
    found = {}
    for key, value in tree.items():
        found.update(_parameters_of(value, f"{prefix}.{key}" if prefix else str(key)))
    return found


def _yaml_value(text: str) -> object:
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text  # rcl takes what YAML cannot read as a string
