"""The one error map of ``spco serve``: every error, spco's and the web framework's, as
``{"error": message, "status": code}`` with the HTTP status of its kind.

========================================================  ======
domain error                                               status
========================================================  ======
malformed JSON                                             400
no or wrong token                                          401
a cross-site request (foreign ``Origin``), a page framed   403
an unknown place name, sample, teaching seq; no endpoint   404
a method the endpoint does not take                        405
a body that did not arrive in time                         408
a teaching that conflicts with the home (an id taken, …)   409
a body or image too large                                  413
not JSON (``Content-Type``)                                415
a well-formed request with wrong values                    422
too many teachings a minute (``TeachingRateError``)        429
a server at one of its limits (subscribers, connections)   503
the writer gone: no teaching possible                      503
a bug                                                      500
========================================================  ======

An error class may say its own status with an ``http_status`` attribute (e.g. 429 for a limit on
teachings). 5xx answers never carry the exception's text (it can name files or processes): they say
what happened in general and the full text goes to the server's log (logger ``spco.serve``).
"""

from __future__ import annotations

import logging
from typing import Any

from starlette.responses import JSONResponse

from spco.errors import SpcoError
from spco.features.pixels import ImageTooLargeError
from spco.model.prediction import UnknownNameError
from spco.service.teaching import ConflictError, NotFoundError
from spco.service.writer import WriterUnavailableError

__all__ = ["LimitError", "error_response", "log", "status_of"]

log = logging.getLogger("spco.serve")


class LimitError(SpcoError):
    """A request refused by one of the server's limits (``status``: 413, 503, …)."""

    def __init__(self, message: str, status: int = 503) -> None:
        super().__init__(message)
        self.http_status = status


#: What a client is told of a 5xx, per status (the details go to the log).
_PUBLIC = {500: "internal error of the server (the details are in the server's log)",
           503: "the server cannot take this request now (see the server's log)"}
_WRITER_GONE = ("the served home takes no teachings now: its writer is gone or cannot write its journal "
                "(answers go on; the details are in the server's log)")


def status_of(exc: BaseException) -> int:
    """The HTTP status of a domain error (see the module's table)."""
    status = getattr(exc, "http_status", None)
    if isinstance(status, int) and 400 <= status <= 599:
        return status
    if isinstance(exc, UnknownNameError | NotFoundError):
        return 404
    if isinstance(exc, ConflictError):
        return 409
    if isinstance(exc, ImageTooLargeError):
        return 413
    if isinstance(exc, WriterUnavailableError):
        return 503
    if isinstance(exc, SpcoError):
        return 422
    return 500


def error_response(status: int, message: str, headers: dict[str, str] | None = None) -> JSONResponse:
    """The one error shape: ``{"error": message, "status": status}``."""
    return JSONResponse({"error": message, "status": status}, status_code=status, headers=headers)


def answer_for(exc: BaseException, where: str = "") -> JSONResponse:
    """The error answer of ``exc``: its message for a 4xx, a general one for a 5xx (logged in full)."""
    status = status_of(exc)
    if status < 500:
        return error_response(status, str(exc))
    if isinstance(exc, WriterUnavailableError):
        log.error("%s: %s", where or "request", exc)
        return error_response(status, _WRITER_GONE)
    if status == 500:
        log.error("%s: internal error", where or "request", exc_info=exc)
    else:
        log.warning("%s: %s", where or "request", exc)
    message = str(exc) if isinstance(exc, LimitError) else _PUBLIC.get(status, "server error")
    return error_response(status, message)


def validation_answer(problems: list[dict[str, Any]], content_type: str) -> JSONResponse:
    """The answer to a request the framework could not validate (pydantic's ``errors()``)."""
    first = problems[0] if problems else {}
    if first.get("type") == "json_invalid":
        return error_response(400, f"malformed JSON: {first.get('ctx', {}).get('error', 'cannot parse it')}")
    where = ".".join(str(p) for p in first.get("loc", ()) if p not in ("body", "query", "path"))
    if first.get("type") == "model_attributes_type" or (not where and first.get("type") == "missing"):
        if not content_type.startswith("application/json"):
            return error_response(415, f"expected a JSON body (Content-Type: application/json), got "
                                       f"{content_type or 'none'!r}")
        return error_response(422, "expected a JSON object")
    more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
    return error_response(422, f"{where or 'request'}: {first.get('msg', 'invalid')}{more}")


#: The framework's own errors (no route, wrong method, …): what a client is told.
FRAMEWORK_MESSAGES = {404: "no such endpoint (see /openapi.json)",
                      405: "this endpoint does not take that method (see /openapi.json)"}
