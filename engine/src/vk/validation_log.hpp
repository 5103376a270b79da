// The validation-layer messages of every Context in this process that their owners have not cleared, since the last
// mark. The test programs mark it when a test starts and fail the test when it ends with a message here
// (tests/support/gpu.cpp), whichever context received it: the shared test context, a test's own, or one inside a
// public dvs::Context (under tests/run_with_sync_validation.sh, DVS_VALIDATION=1 turns the layer on in those too,
// and a test about the public API reads no context's messages itself).
#pragma once
#include <string>
#include <vector>

namespace dvs::vk::validation_log {

// `source` is the context that received the message (only compared, never used).
void add(const void* source, const std::string& message);
void clear(const void* source);          // its owner has read and cleared them
void forget_source(const void* source);  // the context goes: its unread messages stay, bound to no context
void mark();                             // forget every message so far
std::vector<std::string> unread();       // added since the mark and not cleared, oldest first

}  // namespace dvs::vk::validation_log
