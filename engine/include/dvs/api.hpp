// What the installed library exports (dvs/api.h, shared with the C header dvs/dvs.h): DVS_API on every declaration
// of the public API.
#pragma once
#include "dvs/api.h"
