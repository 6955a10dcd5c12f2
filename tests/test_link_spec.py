"""The link spec as the extension parses it (`_native.parse_link`), and that `Master(link)` and the node's parameter
check accept and refuse the same specs with the same message."""

from __future__ import annotations

import socket

import pytest

from akd_ros import _native, params


@pytest.mark.parametrize(
    ("spec", "kind", "count", "missed", "address", "name", "text"),
    [
        ("sim", "sim", 1, "late", None, None, "sim:1"),
        ("sim:64", "sim", 64, "late", None, None, "sim:64"),
        ("sim:2?missed=late", "sim", 2, "late", None, None, "sim:2"),
        ("sim?missed=lost", "sim", 1, "lost", None, None, "sim:1?missed=lost"),
        ("sim:6?missed=lost", "sim", 6, "lost", None, None, "sim:6?missed=lost"),
        ("sim:6?missed=warn", "sim", 6, "warn", None, None, "sim:6?missed=warn"),
        ("sim:6?pace=immediate&missed=warn", "sim", 6, "warn", None, None, "sim:6?missed=warn&pace=immediate"),
        ("sim:EK1100,el1004,el2004,akd", "sim", 4, "late", None, None, "sim:ek1100,el1004,el2004,akd"),
        ("sim:akd,akd?missed=lost", "sim", 2, "lost", None, None, "sim:2?missed=lost"),
        ("udp://127.0.0.1:34980", "udp", None, None, "127.0.0.1:34980", None, "udp://127.0.0.1:34980"),
        ("udp://[::1]:7000", "udp", None, None, "[::1]:7000", None, "udp://[::1]:7000"),
        ("eth0", "interface", None, None, None, "eth0", "eth0"),
        ("eth0?busy_poll=0", "interface", None, None, None, "eth0", "eth0"),
        ("eth0?busy_poll=200", "interface", None, None, None, "eth0", "eth0?busy_poll=200"),
    ],
)
def test_each_form_parses_into_its_kind_and_field(spec, kind, count, missed, address, name, text):
    parsed = _native.parse_link(spec)
    assert (parsed.kind, parsed.count, parsed.missed, parsed.address, parsed.name) == (
        kind,
        count,
        missed,
        address,
        name,
    )
    assert str(parsed) == text and _native.parse_link(text).kind == kind
    busy_poll = spec.partition("?busy_poll=")[2]
    assert parsed.busy_poll_us == (int(busy_poll or 0) if kind == "interface" else None)
    assert parsed.pace == (("immediate" if "pace=immediate" in spec else "real") if kind == "sim" else None)
    if kind == "sim" and "," in spec:
        assert parsed.line == spec.partition(":")[2].partition("?")[0].lower().split(",")
    elif kind == "sim":
        assert parsed.line == ["akd"] * count
    else:
        assert parsed.line is None


def test_a_line_with_terminals_is_opened_by_the_master_and_taken_by_the_node():
    with _native.Master("sim:ek1100,el1004,akd?pace=immediate") as master:
        assert [s["order"] for s in master.scan()] == ["EK1100", "EL1004", "AKD"]
    assert params.check_link("sim:ek1100,el1004,akd") == "sim:ek1100,el1004,akd"


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("sim:0", "the number of virtual AKDs must be 1..=64"),
        ("sim:65", "the number of virtual AKDs must be 1..=64"),
        ("sim:100", "the number of virtual AKDs must be 1..=64"),
        ("sim:x", 'the slave at position 0, "x", is no product the simulator makes: allowed are akd, ek1100'),
        ("sim:ek1100,el9999", 'the slave at position 1, "el9999", is no product the simulator makes'),
        ("sim:ek1100,,akd", 'the slave at position 1, "", is no product the simulator makes'),
        ("sim:akd,el1004", "the slave at position 1, el1004, is an E-bus terminal: an ek1100 or another terminal"),
        ("sim:0?missed=lost", "the number of virtual AKDs must be 1..=64"),
        ("sim:2?missed=soon", "missed=late (the default"),
        ("sim?lost", "missed=lost (only frames lost on the line"),
        ("sim?missed=warn&missed=late", "missed=warn (judged as the real drive"),
        ("sim:2?pace=slow", "pace=immediate (at once"),
        ("udp://127.0.0.1", "udp://HOST:PORT with a port in 1..65535"),
        ("udp://127.0.0.1:0", "udp://HOST:PORT with a port in 1..65535"),
        ("udp://127.0.0.1:65536", "udp://HOST:PORT with a port in 1..65535"),
        ("eth0?busy_poll=1001", "?busy_poll=US with US in 0..=1000"),
        ("eth0?busy_poll=-1", "?busy_poll=US with US in 0..=1000"),
        ("eth0?spin=5", "a network interface takes one option, ?busy_poll=US"),
        ("", _native.LINK_FORMS),
        ("/dev/eth0", _native.LINK_FORMS),
        ("127.0.0.1:34980", _native.LINK_FORMS),
    ],
)
def test_a_bad_spec_is_refused_alike_by_the_parser_the_master_and_the_parameter_check(spec, expected):
    with pytest.raises(_native.ConfigError) as parsed:
        _native.parse_link(spec)
    message = str(parsed.value)
    assert message.startswith(f'link "{spec}"') and expected in message, message
    with pytest.raises(_native.ConfigError) as opened:
        _native.Master(spec)
    assert str(opened.value) == f"configuration: {message}"
    with pytest.raises(params.ParameterError) as checked:
        params.check_link(spec)
    assert str(checked.value) == f"parameter {message}"


def test_the_allowed_forms_name_every_form_and_the_range_of_n():
    for form in (
        "'sim'",
        "'sim:N' (N 1..=64",
        "'sim:P1,P2,...'",
        "akd, ek1100, el1004, el1008, el2004, el2008, el3102",
        "'?missed=late|lost|warn'",
        "'?pace=real|immediate'",
        "'udp://HOST:PORT'",
        "network interface name",
        "'?busy_poll=US'",
    ):
        assert form in _native.LINK_FORMS


def test_the_parameter_check_takes_an_interface_of_this_machine_only():
    here = socket.if_nameindex()[0][1]
    assert params.check_link(here) == here
    with pytest.raises(params.ParameterError, match="'akd_missing0' does not exist; allowed: 'sim'"):
        params.check_link("akd_missing0")
