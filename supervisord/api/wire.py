"""The API's name for the wire's codec (:mod:`supervisord.wire`), which the stop record
shares and so lives outside the API."""

from supervisord.wire import Fields, JsonDict, Wire, WireError, from_json, to_json, wire

__all__ = ["Fields", "JsonDict", "Wire", "WireError", "from_json", "to_json", "wire"]
