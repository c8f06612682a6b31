#pragma once
// Which physics and protocol code this program was built from: the project version and a hash
// of every source file under common/, idl/ and services/dds/ (cmake/BuildIdentity.cmake,
// computed at build time). Processes announce it and checkpoints record it, so that hosts or
// checkpoints of different builds never meet silently, even when message and section versions
// agree.
namespace syndds {

/// "VERSION+HASH", e.g. "0.1.0+3f2a9c0d1e4b5a67".
const char* build_identity();

}  // namespace syndds
