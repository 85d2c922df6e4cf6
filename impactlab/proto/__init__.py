"""Generated protobuf bindings of `schemas/*.proto` (do not edit; run `just schemas`)."""
