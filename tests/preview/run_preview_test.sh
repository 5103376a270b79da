#!/usr/bin/env bash
# The embedding proof (issue 22): builds examples/preview OUT OF TREE against an installed dvs, runs a scripted
# flight under Xvfb on the Vulkan device there is (CI: lavapipe), and checks it by value against the dvs program:
#   (a) the render-panel screenshots equal `dvs render --trajectory <exported path> --save-npy` at those frames
#       (8-bit quantisation of the f32: within 1 level; the visibility mask exactly);
#   (b) the exported JSON holds exactly the poses the preview printed, `dvs render` reads it back to the same
#       doubles (its poses.json), and reads the exported .glb to the same poses within float precision (1e-5);
#   (c) the preview's frame times at 480x720 (mean / median over 60 frames);
#   (d) a run from a VIDEO (288x512, cropped and scaled to 480x720) and its .npz depth whose disparity range spans
#       the clip (a box moving closer), at --frame-index 3: the panel at path frame 3 equals `dvs render`'s frame 3
#       (the depth converted over the whole clip and mapped to the working size as dvs render maps it);
#   (e) the same video with --depth-model (the conformance pack's tiny Video-Depth-Anything, network input 28): the
#       preview estimates the clip itself; its panel at path frame 3 equals `dvs render --depth-model`'s frame 3;
#       and --frame-index past the clip's end is refused naming --frame-index, not options never given (--frames);
#   (f) frames are capped (default 60 a second: FIFO alone does not throttle under Xvfb) and the camera moves per
#       second of wall time: W held for 30 frames at --max-fps 20 (≥ 1.5 s) flies ≥ 0.9 orbit radii, and at either
#       cap 0.6 radii a second of the run's own frame rate (per displayed frame it was 0.3 at any rate).
# usage: run_preview_test.sh PREFIX BUILD_DIR
#   PREFIX: an installed dvs (cmake --install); "-" installs BUILD_DIR into a temporary prefix first.
#   BUILD_DIR: the dvs build (its bin/dvs is used when PREFIX has none).
# Needs: cmake, a C++ compiler, libglfw3-dev, zlib, xvfb-run (xvfb, xauth), python3.
# PREVIEW_EXTRA_ARGS: more dvs-preview options for both runs, for diagnosis (e.g. --dvs-own-device: dvs on a device
# of its own instead of the window's; ctest sets none, so the test proves the embedding).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
source_dir=$(cd "$here/../.." && pwd)
prefix=${1:?usage: run_preview_test.sh PREFIX BUILD_DIR}
build=$(cd "${2:?usage: run_preview_test.sh PREFIX BUILD_DIR}" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/dvs_preview_test.XXXXXX")
trap 'rm -rf "$work"' EXIT
H=480 W=720 FRAMES=5

for tool in xvfb-run python3 cmake; do
  command -v "$tool" >/dev/null || { echo "run_preview_test: $tool is not installed (Debian: xvfb xauth python3 cmake; see .ci/deps)"; exit 1; }
done
if [ "$prefix" = "-" ]; then
  prefix="$work/prefix"
  cmake --install "$build" --prefix "$prefix" >/dev/null
fi
prefix=$(cd "$prefix" && pwd)
dvs="$prefix/bin/dvs"
[ -x "$dvs" ] || dvs="$build/dvs"

echo "== building examples/preview against $prefix"
t0=$(date +%s)
cmake -S "$source_dir/examples/preview" -B "$work/build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" >"$work/configure.log" 2>&1 \
  || { cat "$work/configure.log"; echo "run_preview_test: configuring examples/preview failed"; exit 1; }
cmake --build "$work/build" -j2 >"$work/build.log" 2>&1 || { cat "$work/build.log"; echo "run_preview_test: building examples/preview failed"; exit 1; }
echo "built in $(( $(date +%s) - t0 )) s"
preview="$work/build/dvs-preview"

echo "== the scene: $FRAMES copies of a synthetic ${H}x${W} frame and its disparity"
python3 "$here/make_scene.py" "$work/scene" $H $W $FRAMES
xvfb=(xvfb-run -a -s "-screen 0 2400x600x24")

echo "== the scripted flight"
cd "$work"
"${xvfb[@]}" "$preview" --frame-npy scene/frames.npy --depth scene/depth.npy --size ${H}x${W} --frames $FRAMES \
  --script "$here/preview_script.txt" --validation ${PREVIEW_EXTRA_ARGS:-} >preview.log 2>&1 || { cat preview.log; echo "run_preview_test: the preview failed"; exit 1; }
cat preview.log
if grep -q "validation:" preview.log; then echo "run_preview_test: validation messages (above)"; exit 1; fi
for f in shot_key2.npy shot_frame3.npy path.json path.glb; do
  [ -s "$f" ] || { echo "run_preview_test: the preview did not write $f"; exit 1; }
done

echo "== (a) the render panel against dvs render --save-npy"
"$dvs" render --video scene/frames.npy --depth scene/depth.npy --size ${H}x${W} --frames $FRAMES --no-glb \
  --trajectory path.json --save-npy --out from_json >render_json.log 2>&1 || { cat render_json.log; exit 1; }
python3 "$here/compare_preview.py" panel shot_key2.npy from_json/render.npy from_json/mask.npy $((FRAMES - 1))
python3 "$here/compare_preview.py" panel shot_frame3.npy from_json/render.npy from_json/mask.npy 3

echo "== (b) the exported path round-trips"
python3 "$here/compare_preview.py" poses preview.log path.json 0
python3 "$here/compare_preview.py" poses preview.log from_json/poses.json 0
"$dvs" render --video scene/frames.npy --depth scene/depth.npy --size ${H}x${W} --frames $FRAMES --no-glb \
  --trajectory path.glb --out from_glb >render_glb.log 2>&1 || { cat render_glb.log; exit 1; }
python3 "$here/compare_preview.py" poses preview.log from_glb/poses.json 1e-5

echo "== (c) frame times at ${H}x${W}, the camera moving and turning"
printf 'key D 20\nmouse -40 5\nkey W 20\nmouse 40 -5\nkey A 20\nquit\n' >timing_script.txt
"${xvfb[@]}" "$preview" --frame-npy scene/frames.npy --depth scene/depth.npy --size ${H}x${W} --frames-to-run 60 \
  --script timing_script.txt --max-fps 0 --no-vsync \
  ${PREVIEW_EXTRA_ARGS:-} >timing.log 2>&1 || { cat timing.log; echo "run_preview_test: the timing run failed"; exit 1; }
grep "dvs-preview: window on\|frame times over" timing.log

echo "== (f) the frame cap and motion per second, at 96x160"
cd "$work"
python3 "$here/make_scene.py" "$work/small" 96 160 1
small=(--frame-npy small/frames.npy --depth small/depth.npy --size 96x160)
"${xvfb[@]}" "$preview" "${small[@]}" --frames-to-run 90 ${PREVIEW_EXTRA_ARGS:-} >capped.log 2>&1 \
  || { cat capped.log; echo "run_preview_test: the capped run failed"; exit 1; }
python3 "$here/compare_preview.py" rate capped.log 63
printf 'key W 30\nkeypose\nquit\n' >hold_w.txt
for fps in 20 60; do
  "${xvfb[@]}" "$preview" "${small[@]}" --script hold_w.txt --max-fps $fps ${PREVIEW_EXTRA_ARGS:-} >hold_$fps.log 2>&1 \
    || { cat hold_$fps.log; echo "run_preview_test: the run at --max-fps $fps failed"; exit 1; }
  python3 "$here/compare_preview.py" travel hold_$fps.log 30 $fps
done

echo "== (d) from a video and its .npz depth, frame 3 of 5"
video_lib=$(find "$prefix" -name 'libdvs_video.so' -print -quit)
if [ -z "$video_lib" ]; then
  echo "run_preview_test: (d) not run: this dvs has no video component (DVS_VIDEO_IO=OFF)"
else
  python3 "$here/make_scene.py" "$work/clip" 288 512 $FRAMES moving
  c++ -std=c++17 -O1 -o "$work/make_video" "$here/make_video.cpp" $(pkg-config --cflags --libs opencv4) \
    || { echo "run_preview_test: building make_video (OpenCV) failed"; exit 1; }
  "$work/make_video" "$work/clip/frames.rgb" $FRAMES 288 512 "$work/clip/clip.mp4"
  mkdir "$work/video_run" && cd "$work/video_run"
  "${xvfb[@]}" "$preview" --video ../clip/clip.mp4 --depth ../clip/depth.npz --frame-index 3 --size ${H}x${W} \
    --frames $FRAMES --script "$here/preview_script.txt" --validation ${PREVIEW_EXTRA_ARGS:-} >preview.log 2>&1 \
    || { cat preview.log; echo "run_preview_test: the preview from a video failed"; exit 1; }
  if grep -q "validation:" preview.log; then cat preview.log; echo "run_preview_test: validation messages (above)"; exit 1; fi
  "$dvs" render --video ../clip/clip.mp4 --depth ../clip/depth.npz --size ${H}x${W} --frames $FRAMES --no-glb \
    --trajectory path.json --save-npy --out from_json >render_json.log 2>&1 || { cat render_json.log; exit 1; }
  python3 "$here/compare_preview.py" panel shot_frame3.npy from_json/render.npy from_json/mask.npy 3

  echo "== (e) the same video with --depth-model (estimated in the preview), frame 3 of 5"
  vda="$source_dir/tests/golden/vda-A/model/video_depth_anything_tiny.pth"
  t0=$(date +%s)
  mkdir "$work/model_run" && cd "$work/model_run"
  "${xvfb[@]}" "$preview" --video ../clip/clip.mp4 --depth-model "$vda" --depth-input-size 28 --frame-index 3 \
    --size ${H}x${W} --frames $FRAMES --script "$here/preview_script.txt" --validation ${PREVIEW_EXTRA_ARGS:-} \
    >preview.log 2>&1 || { cat preview.log; echo "run_preview_test: the preview with --depth-model failed"; exit 1; }
  if grep -q "validation:" preview.log; then cat preview.log; echo "run_preview_test: validation messages (above)"; exit 1; fi
  grep -q "dvs-preview: estimating the depth of $FRAMES frame" preview.log \
    || { cat preview.log; echo "run_preview_test: the preview did not say it estimated the depth"; exit 1; }
  DVS_CACHE_DIR="$work/model_run/cache" "$dvs" render --video ../clip/clip.mp4 --depth-model "$vda" \
    --depth-input-size 28 --size ${H}x${W} --frames $FRAMES --no-glb --trajectory path.json --save-npy \
    --out from_json >render_json.log 2>&1 || { cat render_json.log; exit 1; }
  python3 "$here/compare_preview.py" panel shot_frame3.npy from_json/render.npy from_json/mask.npy 3
  echo "(e) took $(( $(date +%s) - t0 )) s"

  echo "== (e) --frame-index past the clip's $FRAMES frames names what was given"
  if "${xvfb[@]}" "$preview" --video ../clip/clip.mp4 --depth ../clip/depth.npz --frame-index 7 --size ${H}x${W} \
      --frames-to-run 1 >past_end.log 2>&1; then
    cat past_end.log; echo "run_preview_test: --frame-index 7 of a $FRAMES-frame clip was accepted"; exit 1
  fi
  cat past_end.log
  grep -q -- "--frame-index 7: .*frame 7 asked for, but the video holds $FRAMES frames" past_end.log \
    || { echo "run_preview_test: the message does not name --frame-index 7 and the clip's $FRAMES frames"; exit 1; }
  if grep -q -- "--frames" past_end.log; then echo "run_preview_test: the message names --frames, never given"; exit 1; fi
  if "$preview" --video ../clip/clip.mp4 --depth-model "$vda" --frame-index 60 >past_model.log 2>&1; then
    cat past_model.log; echo "run_preview_test: --frame-index 60 past --depth-model's 49 frames was accepted"; exit 1
  fi
  cat past_model.log
  grep -q -- "--frame-index 60 is past the 49 frames --depth-model estimates by default" past_model.log \
    || { echo "run_preview_test: the message does not say the 49 frames are the default (--frames was not given)"; exit 1; }
fi
echo "run_preview_test: passed"
