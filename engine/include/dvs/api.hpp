// What the installed library exports. libdvs is built with hidden symbols; every declaration of the public API
// (engine/include/dvs/) carries DVS_API, everything else stays inside the library.
#pragma once

#if defined(_WIN32)
#define DVS_API __declspec(dllexport)
#else
#define DVS_API __attribute__((visibility("default")))
#endif
