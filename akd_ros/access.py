"""Who may use which door of akd_node over Zenoh: the roles, a small certificate authority, and each party's Zenoh
configuration with mutual TLS and the access-control rules of its role (what `akd-access init` writes).

Every door the node declares (`akd_ros.node.interface.declared`) has the role `akd_ros.node.doors` gives it:
observe, operate or configure. A client's role is the common name of its certificate. The rules are the node's:
the node's session listens with mutual TLS, so a client without a certificate of this authority cannot connect, and
Zenoh's access control on the node's session lets an observer subscribe only, an operator also put commands and query
the operating services and actions, and a configurer the rest. Anything no rule allows is denied before it reaches the
node.

Between machines a router may stand in front of the node (`router_config`): it listens where the clients connect,
with the same mutual TLS and the same rules for them, and connects to the node; the node and the router trust each
other's certificate with everything, the router having judged its clients already.
"""

from __future__ import annotations

import datetime
import ipaddress
import json
import os
from pathlib import Path

from akd_ros.node import doors
from akd_ros.node.doors import CLIENTS
from akd_ros.node.interface import ACTION, SERVICE, SUBSCRIPTION, Endpoint
from akd_ros.params import DOOR_ROLES as ROLES

OBSERVE, OPERATE, CONFIGURE = ROLES
NODE = "akd-node"
"""The node's certificate common name; its files are node.*."""
ROUTER = "akd-router"
"""The certificate common name of a router in front of the node; its files are router.*."""
ACL_MESSAGES = {
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
}
"""Every kind of message Zenoh's access control judges."""
VALIDITY_DAYS = 825
"""How long the certificates are valid by default: the longest a TLS server certificate is commonly accepted for."""


def role_of(endpoint: Endpoint) -> str:
    """The role whose clients may use `endpoint` (each role may use the doors of the roles before it too)."""
    return doors.role_of(endpoint.kind, endpoint.name)


def door_key_exprs(endpoint: Endpoint, node_name: str) -> list[str]:
    """The Zenoh key expressions of a door of the node `node_name` as rmw_zenoh names it (<domain>/<name>/<type>/<hash>,
    an action's services under <name>/_action/), in any domain and namespace and for any joint."""
    name = doors.door_name(endpoint.name)
    return [f"*/**/{node_name}/{name}/**", f"*/**/{node_name}/*/{name}/**"]


def access_control(endpoints: list[Endpoint], node_name: str, trusted: str | None = None) -> dict:
    """Zenoh's access_control section for the node (or a router in front of it): the rules of each role over
    `endpoints` (the node's doors), its subjects by certificate common name, everything for the certificate named
    `trusted` (the router's at the node, the node's at the router), deny for everything else."""
    commands = {role: _role_rules(endpoints, node_name, role, (SUBSCRIPTION,)) for role in ROLES}
    queries = {role: _role_rules(endpoints, node_name, role, (SERVICE, ACTION)) for role in ROLES}
    rules = [
        {
            "id": "observe",
            "messages": ["declare_subscriber", "liveliness_token", "declare_liveliness_subscriber", "liveliness_query"],
            "flows": ["ingress", "egress"],
            "permission": "allow",
            # ** matches no chunk that starts with @ (a verbatim chunk): the graph's tokens are named apart.
            "key_exprs": ["**", "@ros2_lv/**"],
        },
        # The graph: who is who, which the node also asks to name a request's sender.
        {
            "id": "graph",
            "messages": ["reply"],
            "flows": ["ingress", "egress"],
            "permission": "allow",
            "key_exprs": ["@ros2_lv/**"],
        },
        {
            "id": "to_clients",
            "messages": ["put", "reply"],
            "flows": ["egress"],
            "permission": "allow",
            "key_exprs": ["**"],
        },
    ]
    for role in (OPERATE, CONFIGURE):
        # A service is a queryable the node declares: the client must hear of it (egress) to send its query
        # (ingress) to the node.
        for what, messages, flow, keys in (
            ("commands", ["put"], "ingress", commands[role]),
            ("requests", ["query"], "ingress", queries[role]),
            ("services", ["declare_queryable"], "egress", queries[role]),
        ):
            if keys:
                rules.append(
                    {
                        "id": f"{role}_{what}",
                        "messages": messages,
                        "flows": [flow],
                        "permission": "allow",
                        "key_exprs": keys,
                    }
                )
    granted = {
        role: [
            r["id"]
            for r in rules
            if r["id"] in ("observe", "graph", "to_clients") or r["id"].split("_")[0] in ROLES[: ROLES.index(role) + 1]
        ]
        for role in ROLES
    }
    subjects = [{"id": CLIENTS[role], "cert_common_names": [CLIENTS[role]]} for role in ROLES]
    policies = [{"id": CLIENTS[role], "rules": granted[role], "subjects": [CLIENTS[role]]} for role in ROLES]
    if trusted:
        rules.append(
            {
                "id": "trusted",
                "messages": sorted(ACL_MESSAGES),
                "flows": ["ingress", "egress"],
                "permission": "allow",
                "key_exprs": ["**", "@ros2_lv/**"],
            }
        )
        subjects.append({"id": trusted, "cert_common_names": [trusted]})
        policies.append({"id": trusted, "rules": ["trusted"], "subjects": [trusted]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def _role_rules(endpoints: list[Endpoint], node_name: str, role: str, kinds: tuple[str, ...]) -> list[str]:
    return sorted(
        {k for e in endpoints if e.kind in kinds and role_of(e) == role for k in door_key_exprs(e, node_name)}
    )


def tls(directory: Path, who: str, listening: bool) -> dict:
    """The transport/link/tls section of `who`'s configuration (its key and certificate in `directory`): mutual TLS,
    this authority's certificates only; the node's name is checked against the endpoint a client connects to."""
    section = {"root_ca_certificate": str(directory / "ca.pem"), "enable_mtls": True, "verify_name_on_connect": True}
    for side in ("listen", "connect") if listening else ("connect",):
        section[f"{side}_private_key"] = str(directory / f"{who}.key")
        section[f"{side}_certificate"] = str(directory / f"{who}.pem")
    return section


def node_config(
    directory: Path, endpoint: str, endpoints: list[Endpoint], node_name: str, router: bool = False
) -> dict:
    """The node's Zenoh configuration: a peer listening on `endpoint` with mutual TLS and the roles' access control
    (`router`: and a router in front of it trusted), as rmw_zenoh's default otherwise (multicast scouting off,
    timestamps on)."""
    return {
        "mode": "peer",
        "listen": {"endpoints": [endpoint]},
        "connect": {"endpoints": []},
        "scouting": {"multicast": {"enabled": False}},
        "timestamping": {"enabled": {"router": True, "peer": True, "client": True}},
        "transport": {"link": {"tls": tls(directory, "node", listening=True)}},
        "access_control": access_control(endpoints, node_name, ROUTER if router else None),
    }


def router_config(directory: Path, endpoint: str, node_endpoint: str, endpoints: list[Endpoint], node_name: str):
    """A router's Zenoh configuration: listening for the clients on `endpoint` with mutual TLS and the roles' access
    control, connected to the node at `node_endpoint` (whose certificate it trusts), as rmw_zenohd's default
    otherwise."""
    return {
        "mode": "router",
        "listen": {"endpoints": [endpoint]},
        "connect": {"endpoints": [node_endpoint]},
        "scouting": {"multicast": {"enabled": False}},
        "timestamping": {"enabled": {"router": True, "peer": True, "client": True}},
        "transport": {"link": {"tls": tls(directory, "router", listening=True)}},
        "access_control": access_control(endpoints, node_name, NODE),
    }


def client_config(directory: Path, endpoint: str, role: str, router: bool = False) -> dict:
    """A client of `role`'s Zenoh configuration, connecting to `endpoint` with its certificate, listening nowhere: a
    peer (as rmw_zenoh's nodes are) connecting to the node, or (`router`) a client of the router there, which talks
    to nothing but it."""
    return {
        "mode": "client" if router else "peer",
        "connect": {"endpoints": [endpoint]},
        "listen": {"endpoints": []},
        "scouting": {"multicast": {"enabled": False}},
        "timestamping": {"enabled": {"router": True, "peer": True, "client": True}},
        "transport": {"link": {"tls": tls(directory, CLIENTS[role], listening=False)}},
    }


def endpoint_host(endpoint: str, option: str = "--endpoint") -> str:
    """The host of a tls/HOST:PORT endpoint (an IPv6 address without its brackets) given as `option`; ValueError
    naming the form."""
    protocol, _, address = endpoint.partition("/")
    host, _, port = address.rpartition(":")
    host = host.strip("[]")
    if protocol != "tls" or not host or not port.isascii() or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"{option} {endpoint!r} is not of the form tls/HOST:PORT (e.g. tls/192.168.1.10:7447)")
    return host


def write_authority(directory: Path, host: str, days: int = VALIDITY_DAYS, router_host: str | None = None) -> None:
    """Writes a certificate authority (ca.pem, ca.key) and a key and certificate signed by it for the node (named
    for `host`, as clients check it), for a router in front of it when `router_host` is given (named for that host),
    and for each role's client (named after the role), in `directory`; keys are readable by their owner only."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    now = datetime.datetime.now(datetime.timezone.utc)

    def name(common_name: str) -> x509.Name:
        return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])

    def save(stem: str, key, certificate) -> None:
        key_path = directory / f"{stem}.key"
        key_path.write_bytes(
            key.private_bytes(
                serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
            )
        )
        os.chmod(key_path, 0o600)
        (directory / f"{stem}.pem").write_bytes(certificate.public_bytes(serialization.Encoding.PEM))

    def issued(subject: str, public_key, *extensions) -> x509.CertificateBuilder:
        builder = (
            x509.CertificateBuilder()
            .subject_name(name(subject))
            .issuer_name(name("akd_ros access authority"))
            .public_key(public_key)
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=days))
        )
        for extension, critical in extensions:
            builder = builder.add_extension(extension, critical=critical)
        return builder

    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca = issued(
        "akd_ros access authority",
        ca_key.public_key(),
        (x509.BasicConstraints(ca=True, path_length=0), True),
        (x509.KeyUsage(False, False, False, False, False, True, True, False, False), True),
    ).sign(ca_key, hashes.SHA256())
    save("ca", ca_key, ca)

    def alternative(host: str) -> x509.GeneralName:
        try:
            return x509.IPAddress(ipaddress.ip_address(host))
        except ValueError:
            return x509.DNSName(host)

    parties = [("node", NODE, [alternative(host)])] + [(c, c, []) for c in CLIENTS.values()]
    if router_host is not None:
        parties.append(("router", ROUTER, [alternative(router_host)]))
    for stem, common_name, names in parties:
        key = ec.generate_private_key(ec.SECP256R1())
        usage = [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
        extensions = [(x509.BasicConstraints(ca=False, path_length=None), True), (x509.ExtendedKeyUsage(usage), False)]
        if names:
            extensions.append((x509.SubjectAlternativeName(names), False))
        save(stem, key, issued(common_name, key.public_key(), *extensions).sign(ca_key, hashes.SHA256()))


def write_configs(
    directory: Path, endpoint: str, endpoints: list[Endpoint], node_name: str, router: str | None = None
) -> list[Path]:
    """Writes node.json5, router.json5 when a router listens at `router` in front of the node, and a configuration
    per role's client (connecting to the router if any, else to the node) in `directory`; the files written."""
    configs = {"node": node_config(directory, endpoint, endpoints, node_name, router=router is not None)}
    if router is not None:
        configs["router"] = router_config(directory, router, endpoint, endpoints, node_name)
    for role in ROLES:
        configs[CLIENTS[role]] = client_config(directory, router or endpoint, role, router=router is not None)
    written = []
    for stem, config in configs.items():
        path = directory / f"{stem}.json5"
        path.write_text(json.dumps(config, indent=2) + "\n")
        written.append(path)
    return written
