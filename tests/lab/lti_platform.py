"""A small LTI 1.3 platform for the tests: real RSA keys, JWKS over HTTP, signed JWTs.

It plays the LMS's part of every flow, over real HTTP on 127.0.0.1:

* ``GET /jwks`` — its public keys (rotatable: :meth:`Platform.rotate`);
* ``GET /start/<hint>`` — a page that starts a launch at the tool (the LMS's
  link), posting the OIDC login initiation;
* ``GET /course/<hint>`` — a course page showing the tool in an iframe;
* ``GET /auth`` — the OIDC authorisation endpoint: checks the tool's request
  and answers a page that posts a signed ``id_token`` to the tool;
* ``POST /token`` — OAuth 2 client credentials: checks the tool's signed
  assertion against the tool's JWKS, gives an access token;
* ``GET /nrps/<context>`` — the roster (NRPS), in two pages;
* ``POST /lineitems/<id>/scores`` — scores (AGS) into a gradebook the tests read;
* ``POST /deep-link-return`` — the tool's deep-linking answer, checked and kept.

Written for the tests from the IMS specifications; nothing here is a stub of
the lab: the lab talks to it as to any LMS.
"""

from __future__ import annotations

import json
import secrets
import threading
import time
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass, field
from html import escape
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, ClassVar
from urllib.parse import parse_qs, urlencode, urlsplit

import jwt
from cryptography.hazmat.primitives.asymmetric import rsa
from jwt.algorithms import RSAAlgorithm

LTI = "https://purl.imsglobal.org/spec/lti/claim/"
DL = "https://purl.imsglobal.org/spec/lti-dl/claim/"
LEARNER = "http://purl.imsglobal.org/vocab/lis/v2/membership#Learner"
INSTRUCTOR = "http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor"


@dataclass
class Person:
    """A user of the platform."""

    sub: str
    name: str
    roles: list[str]
    username: str | None = None
    status: str = "Active"


@dataclass
class PendingLaunch:
    """What the next launch with a login hint sends."""

    person: Person
    message_type: str = "LtiResourceLinkRequest"
    custom: dict[str, str] = field(default_factory=dict)
    # A way to spoil the id_token: {"exp": -3600}, {"aud": "other"}, {"deployment": "x"},
    # {"drop": ["roles"]}, {"claims": {"resource_link": {}}}, {"dl_settings": {...}}...
    spoil: dict[str, Any] = field(default_factory=dict)


def _new_key() -> tuple[Any, dict[str, Any]]:
    private = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    public = json.loads(RSAAlgorithm.to_jwk(private.public_key()))
    public.update({"kid": secrets.token_hex(8), "alg": "RS256", "use": "sig"})
    return private, public


class Platform:
    """The test LMS. Start with :meth:`start`; its URL is :attr:`url`."""

    client_id = "thermolab-tool"
    deployment_id = "deployment-1"
    context: ClassVar[dict[str, str]] = {
        "id": "ctx-42",
        "label": "ENG-3020",
        "title": "Controle de Processos",
    }

    def __init__(self, tool_jwks: Callable[[], dict[str, Any]], host: str = "127.0.0.1") -> None:
        self._tool_jwks = tool_jwks
        self._key, self._jwk = _new_key()
        self._old_jwks: list[dict[str, Any]] = []
        self.pending: dict[str, PendingLaunch] = {}
        self.roster: list[Person] = []
        self.gradebook: dict[tuple[str, str], dict[str, Any]] = {}
        self.fail_scores = 0
        self.deep_link_items: list[dict[str, Any]] = []
        self.tokens: set[str] = set()
        self.tool_url = ""
        self._server = ThreadingHTTPServer(("127.0.0.1", 0), self._handler())
        # ``host="localhost"`` makes the platform another *site* than a lab on 127.0.0.1
        # (ports do not make sites), so its iframe is a real third-party context.
        self.url = f"http://{host}:{self._server.server_address[1]}"
        self._thread = threading.Thread(
            target=self._server.serve_forever, args=(0.05,), daemon=True
        )

    # -- set-up ------------------------------------------------------------------------
    def start(self) -> Platform:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(5)

    def registration(self, jwks_url: str | None = None) -> dict[str, Any]:
        """The body of the tool's ``POST /api/lti/platforms`` for this platform."""
        return {
            "issuer": self.url,
            "clientId": self.client_id,
            "authLoginUrl": f"{self.url}/auth",
            "tokenUrl": f"{self.url}/token",
            "jwksUrl": jwks_url or f"{self.url}/jwks",
            "deploymentIds": [self.deployment_id],
        }

    def rotate(self) -> None:
        """A new signing key (the old one leaves the key set)."""
        self._key, self._jwk = _new_key()

    def expect(self, hint: str, launch: PendingLaunch) -> None:
        """The launch the login hint ``hint`` will make."""
        self.pending[hint] = launch

    def login_params(self, hint: str, target: str = "") -> dict[str, str]:
        """The OIDC login initiation's parameters for ``hint``."""
        return {
            "iss": self.url,
            "login_hint": hint,
            "target_link_uri": target or f"{self.tool_url}/api/lti/launch",
            "lti_message_hint": f"msg-{hint}",
            "client_id": self.client_id,
            "lti_deployment_id": self.deployment_id,
        }

    # -- the id_token --------------------------------------------------------------------
    def id_token(self, launch: PendingLaunch, nonce: str, redirect_uri: str) -> str:
        now = int(time.time())
        person = launch.person
        spoil = launch.spoil
        claims: dict[str, Any] = {
            "iss": self.url,
            "aud": spoil.get("aud", self.client_id),
            "sub": person.sub,
            "iat": now,
            "exp": now + 300 + int(spoil.get("exp", 0)),
            "nonce": spoil.get("nonce", nonce),
            "name": person.name,
            LTI + "message_type": launch.message_type,
            LTI + "version": "1.3.0",
            LTI + "deployment_id": spoil.get("deployment", self.deployment_id),
            LTI + "target_link_uri": redirect_uri,
            LTI + "roles": person.roles,
            LTI + "context": self.context,
            LTI + "custom": launch.custom,
            LTI + "resource_link": {"id": "link-1"},
            "https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice": {
                "context_memberships_url": f"{self.url}/nrps/{self.context['id']}",
                "service_versions": ["2.0"],
            },
            "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint": {
                "scope": ["https://purl.imsglobal.org/spec/lti-ags/scope/score"],
                "lineitems": f"{self.url}/lineitems",
                "lineitem": f"{self.url}/lineitems/1",
            },
        }
        if person.username:
            claims[LTI + "lis"] = {"person_sourcedid": person.username}
        if launch.message_type == "LtiDeepLinkingRequest":
            claims[DL + "deep_linking_settings"] = {
                "deep_link_return_url": f"{self.url}/deep-link-return",
                "accept_types": ["ltiResourceLink"],
                "accept_presentation_document_targets": ["iframe", "window"],
                "accept_multiple": True,
                "data": "opaque-42",
                **spoil.get("dl_settings", {}),
            }
        # Claims taken out ({"drop": [name]}: a short name of LTI's claims) or replaced.
        for name in spoil.get("drop", ()):
            claims.pop(LTI + name, None)
        for name, value in spoil.get("claims", {}).items():
            claims[LTI + name] = value
        key = spoil.get("key", self._key)
        return jwt.encode(claims, key, algorithm="RS256", headers={"kid": self._jwk["kid"]})

    def authorize(self, query: dict[str, str]) -> tuple[str, str, str]:
        """Check an OIDC authorisation request; return (redirect URI, id_token, state)."""
        assert query["scope"] == "openid"
        assert query["response_type"] == "id_token"
        assert query["response_mode"] == "form_post"
        assert query["prompt"] == "none"
        assert query["client_id"] == self.client_id
        assert query["lti_message_hint"] == f"msg-{query['login_hint']}"
        launch = self.pending[query["login_hint"]]
        redirect = query["redirect_uri"]
        return redirect, self.id_token(launch, query["nonce"], redirect), query["state"]

    # -- the tool's tokens -------------------------------------------------------------
    def check_tool_jwt(self, token: str, audience: str) -> dict[str, Any]:
        kid = jwt.get_unverified_header(token)["kid"]
        keys = [k for k in self._tool_jwks()["keys"] if k["kid"] == kid]
        assert keys, f"no tool key {kid}"
        public = RSAAlgorithm.from_jwk(json.dumps(keys[0]))
        return dict(jwt.decode(token, public, algorithms=["RS256"], audience=audience))  # type: ignore[arg-type]

    # -- HTTP --------------------------------------------------------------------------
    def _handler(self) -> type[BaseHTTPRequestHandler]:
        platform = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, format: str, *args: Any) -> None:
                pass

            def _send(self, status: int, body: str, kind: str = "application/json") -> None:
                data = body.encode("utf-8")
                self.send_response(status)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def _authorised(self) -> bool:
                header = self.headers.get("Authorization", "")
                return header.startswith("Bearer ") and header[7:] in platform.tokens

            def _form(self) -> dict[str, str]:
                size = int(self.headers.get("Content-Length", "0"))
                return {k: v[0] for k, v in parse_qs(self.rfile.read(size).decode()).items()}

            def do_GET(self) -> None:
                parts = urlsplit(self.path)
                query = {k: v[0] for k, v in parse_qs(parts.query).items()}
                if parts.path == "/jwks":
                    self._send(200, json.dumps({"keys": [platform._jwk]}))
                elif parts.path.startswith("/start/"):
                    hint = parts.path.removeprefix("/start/")
                    fields = platform.login_params(hint)
                    self._send(
                        200, _autopost(f"{platform.tool_url}/api/lti/login", fields), "text/html"
                    )
                elif parts.path.startswith("/course/"):
                    hint = parts.path.removeprefix("/course/")
                    page = (
                        "<!doctype html><html><body><h1>LMS course</h1>"
                        f'<iframe id="tool" src="/start/{escape(hint)}" width="1000" '
                        'height="700"></iframe></body></html>'
                    )
                    self._send(200, page, "text/html")
                elif parts.path == "/auth":
                    redirect, token, state = platform.authorize(query)
                    page = _autopost(redirect, {"id_token": token, "state": state})
                    self._send(200, page, "text/html")
                elif parts.path.startswith("/nrps/"):
                    if not self._authorised():
                        self._send(401, "{}")
                        return
                    page = int(query.get("page", "1"))
                    people = platform.roster[:2] if page == 1 else platform.roster[2:]
                    members = [
                        {
                            "status": p.status,
                            "name": p.name,
                            "user_id": p.sub,
                            "roles": p.roles,
                            **({"lis_person_sourcedid": p.username} if p.username else {}),
                        }
                        for p in people
                    ]
                    body = json.dumps({"id": parts.path, "members": members})
                    self.send_response(200)
                    self.send_header("Content-Type", "application/json")
                    if page == 1 and len(platform.roster) > 2:
                        self.send_header("Link", f'<{platform.url}{parts.path}?page=2>; rel="next"')
                    data = body.encode()
                    self.send_header("Content-Length", str(len(data)))
                    self.end_headers()
                    self.wfile.write(data)
                else:
                    self._send(404, "{}")

            def do_POST(self) -> None:
                parts = urlsplit(self.path)
                if parts.path == "/token":
                    form = self._form()
                    assert form["grant_type"] == "client_credentials"
                    claims = platform.check_tool_jwt(
                        form["client_assertion"], f"{platform.url}/token"
                    )
                    assert claims["iss"] == claims["sub"] == platform.client_id
                    token = secrets.token_urlsafe(16)
                    platform.tokens.add(token)
                    self._send(200, json.dumps({"access_token": token, "expires_in": 3600}))
                elif parts.path.endswith("/scores"):
                    size = int(self.headers.get("Content-Length", "0"))
                    body = json.loads(self.rfile.read(size))
                    if not self._authorised():
                        self._send(401, "{}")
                    elif platform.fail_scores > 0:
                        platform.fail_scores -= 1
                        self._send(503, '{"error": "gradebook busy"}')
                    else:
                        item = parts.path.removesuffix("/scores")
                        platform.gradebook[(item, body["userId"])] = body
                        self._send(200, "{}")
                elif parts.path == "/deep-link-return":
                    form = self._form()
                    claims = platform.check_tool_jwt(form["JWT"], platform.url)
                    assert claims[LTI + "message_type"] == "LtiDeepLinkingResponse"
                    assert claims[DL + "data"] == "opaque-42"
                    platform.deep_link_items = claims[DL + "content_items"]
                    self._send(200, "<h1 id=linked>Linked</h1>", "text/html")
                else:
                    self._send(404, "{}")

        return Handler


def _autopost(action: str, fields: dict[str, str]) -> str:
    inputs = "".join(
        f'<input type="hidden" name="{escape(k)}" value="{escape(v)}">' for k, v in fields.items()
    )
    return (
        f'<!doctype html><html><body><form id="f" method="post" action="{escape(action)}">'
        f"{inputs}<button>go</button></form>"
        "<script>document.getElementById('f').submit()</script></body></html>"
    )


def http_jwks(url: str) -> Callable[[], dict[str, Any]]:
    """The tool's JWKS fetched over HTTP each time (for a lab in another process)."""

    def fetch() -> dict[str, Any]:
        with urllib.request.urlopen(url, timeout=10) as answer:
            return dict(json.loads(answer.read()))

    return fetch


__all__ = ["INSTRUCTOR", "LEARNER", "PendingLaunch", "Person", "Platform", "http_jwks"]
_ = urlencode
