"""The protocol's errors, and the root of aioadept's one exception tree.

They live here, inside the sans-IO core, so that :mod:`aioadept.protocol` imports nothing from the rest of the
package; :mod:`aioadept.errors` re-exports them beside the other errors and draws the whole tree. Import them
from :mod:`aioadept.errors` in user code.
"""

from __future__ import annotations


class AdeptError(Exception):
    """Base of every error raised by aioadept."""


class ProtocolError(AdeptError):
    """Bytes on the wire that break the line protocol."""


class LocalProtocolError(ProtocolError):
    """We were asked to encode something the protocol cannot carry (e.g. a line over 128 characters)."""


class RemoteProtocolError(ProtocolError):
    """The peer sent something that does not parse.

    ``code`` is the V+-style error code (see :mod:`aioadept.protocol.codes`) that a server answers with, and ``id``
    the message ID when one could be recovered from the line, so that the error ack can be routed.
    """

    def __init__(self, code: int, message: str, *, id: str | None = None, line: bytes | None = None) -> None:
        super().__init__(f"{message} (code {code})")
        self.code = code
        self.message = message
        self.id = id
        self.line = line
