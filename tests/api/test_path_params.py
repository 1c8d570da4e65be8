"""No path parameter can make the API answer 500: every route of the app's route table,
every method, every path parameter given a hostile value (null bytes, overlong names,
encoded separators and dot segments, invalid UTF-8, control characters) is answered 4xx
as application/problem+json.

The routes are read from the app itself, so a route added later is covered without
touching this test (and a route with path parameters that this test cannot find fails
:func:`test_the_route_table_has_path_parameters`).  The real-server case (uvicorn's own
URL decoding) is tests/e2e/test_bad_paths_server.py.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator

import pytest
from fastapi.testclient import TestClient
from starlette.routing import BaseRoute, Route

from service.app import create_app

#: Hostile values, already percent-encoded as they travel in a request line.
BAD: dict[str, str] = {
    "null byte": "%00",
    "null byte inside a name": "app.js%00.png",
    "null byte then a separator": "%00%2F",
    "name over NAME_MAX (255)": "a" * 300,
    "name over PATH_MAX (4096)": "b" * 5000 + ".js",
    "encoded slash": "..%2F..%2Fetc%2Fpasswd",
    "encoded backslash": "..%5C..%5Cwin.ini",
    "encoded dot segment": "%2E%2E",
    "encoded dot segment and slash": "%2e%2e%2fservice%2fapp.py",
    "invalid UTF-8 byte": "%FF",
    "truncated UTF-8 sequence": "%C3",
    "overlong UTF-8 encoding of '/'": "%C0%AF",
    "UTF-16 surrogate in UTF-8": "%ED%A0%80",
    "control characters": "%0D%0Ax%09",
    "right-to-left override": "%E2%80%AEsj.ppa",
}

_PARAM = re.compile(r"{([^}:]+)(?::[^}]*)?}")


def _route_table(routes: Iterable[BaseRoute], prefix: str = "") -> Iterator[tuple[str, BaseRoute]]:
    """(full path template, route) of every route, included routers walked into
    (FastAPI >= 0.16x keeps an included router as one entry with its own routes)."""
    for r in routes:
        sub = getattr(r, "original_router", None)
        if sub is not None:
            yield from _route_table(sub.routes, prefix + r.include_context.prefix)  # type: ignore[attr-defined]
        elif isinstance(r, Route):
            yield prefix + r.path, r


def _routes() -> list[tuple[str, str, list[str]]]:
    """(method, path template, parameter names) of every route with path parameters."""
    out = []
    for path, r in _route_table(create_app().routes):
        names = _PARAM.findall(path)
        for m in sorted(r.methods or ()) if names else ():
            out.append((m, path, names))
    return out


ROUTES = _routes()
CASES = [
    pytest.param(method, path, param, value, id=f"{method} {path} {param}: {what}")
    for method, path, names in ROUTES
    for param in names
    for what, value in BAD.items()
]


def _url(path: str, param: str, value: str) -> str:
    """``path`` with ``value`` in parameter ``param`` and a plain name in the others."""

    def fill(m: re.Match[str]) -> str:
        return value if m.group(1) == param else "x"

    return _PARAM.sub(fill, path)


@pytest.fixture(scope="module")
def client(api_stack: tuple[TestClient, object]) -> Iterator[TestClient]:
    yield api_stack[0]


def test_the_route_table_has_path_parameters() -> None:
    """The generator sees the routes it is meant to cover (a change of route type or
    template syntax would otherwise silently leave nothing to test)."""
    paths = {p for _m, p, _n in ROUTES}
    for expected in ("/static/{name}", "/docs-assets/{name}"):  # outside the schema
        assert expected in paths, sorted(paths)
    for p in create_app().openapi()["paths"]:
        assert "{" not in p or p in paths, f"{p} of the OpenAPI schema is not in the table"
    assert len(CASES) >= 10 * len(BAD)


@pytest.mark.parametrize(("method", "path", "param", "value"), CASES)
def test_hostile_path_parameter_is_a_4xx_problem(
    client: TestClient, method: str, path: str, param: str, value: str
) -> None:
    url = _url(path, param, value)
    r = client.request(method, url, follow_redirects=False)
    if r.status_code == 307:  # a trailing (decoded) slash: redirected without it, as any path
        assert value.endswith("%2F") and r.headers["location"].endswith(url.removesuffix("%2F"))
        r = client.request(method, url.removesuffix("%2F"), follow_redirects=False)
    assert 400 <= r.status_code < 500, (url[:200], r.status_code, r.text[:300])
    assert r.headers["content-type"].startswith("application/problem+json"), r.headers
    body = r.json()
    assert body["status"] == r.status_code and body["title"] and body["detail"], body
