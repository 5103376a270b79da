/* What the installed library exports. libdvs is built with hidden symbols; every declaration of the public API
 * (engine/include/dvs/) carries DVS_API, everything else stays inside the library. A C header (dvs/dvs.h includes
 * it); dvs/api.hpp is the same for the C++ headers. */
#ifndef DVS_API_H
#define DVS_API_H

#if defined(_WIN32)
#define DVS_API __declspec(dllexport)
#else
#define DVS_API __attribute__((visibility("default")))
#endif

#endif /* DVS_API_H */
