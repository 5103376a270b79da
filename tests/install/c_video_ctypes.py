#!/usr/bin/env python3
"""Video files from Python's ctypes through the installed package (issue 34, docs/c-api.md).

usage: c_video_ctypes.py LIBDIR VIDEO EXPECTED_NOTE OUT_DIR

libdvs.so alone: the render's preflight names the missing video component for VIDEO. Then libdvs_video.so from the
same folder, loaded beside it and enabled with dvs_enable_video_files(): the same preflight decodes VIDEO and notes
EXPECTED_NOTE ("5 frames of 48x64"). Standard library only.
"""
import ctypes as C
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
from test_c_api import RenderOptions  # noqa: E402  (dvs_render_options, field for field)


def preflight(lib, video, out_dir):
    o = RenderOptions()
    assert lib.dvs_render_options_default(C.byref(o)) == 0
    o.video, o.depth, o.out_dir, o.frames = video.encode(), video.encode(), out_dir.encode(), 0
    problems, report = C.c_int32(0), C.create_string_buffer(16384)
    status = lib.dvs_preflight_render(C.byref(o), C.byref(problems), report, len(report), None)
    assert status == 0, lib.dvs_last_error().decode()
    return report.value.decode()


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    libdir, video, expected, out_dir = sys.argv[1:]
    lib = C.CDLL(os.path.join(libdir, "libdvs.so"))
    lib.dvs_last_error.restype = C.c_char_p
    alone = preflight(lib, video, out_dir)
    if "needs dvs's video component" not in alone or "call dvs_enable_video_files()" not in alone:
        sys.exit("libdvs.so alone: the report does not name the video component:\n" + alone)
    video_lib = C.CDLL(os.path.join(libdir, "libdvs_video.so"))
    if video_lib.dvs_enable_video_files() != 0:
        sys.exit("dvs_enable_video_files failed")
    enabled = preflight(lib, video, out_dir)
    if expected not in enabled:
        sys.exit("with libdvs_video: '%s' is not in the report:\n%s" % (expected, enabled))
    print("ctypes: libdvs.so alone names the video component; with libdvs_video.so the video reads (%s)" % expected)


if __name__ == "__main__":
    main()
