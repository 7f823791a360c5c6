#!/usr/bin/env bash
# Frame and relight times of the viewport on a real GPU, for the workplace's device tool (a
# lent machine with an NVIDIA GPU; CI never runs this). It prints `lightloom bench`'s default
# and synthetic sections, where the wavelet modes' relight runs once as the CPU twin and once
# as the compute kernel (wavelet_relight.wgsl), and the sun's shadow-map passes run in both
# sun settings; then the edit-to-frame times of the Cycles comparison's three edits
# (docs/accuracy.md) at its 320x180 and at 1280x720.
#
# Prepare here, once (the machine is bare and reaches nothing):
#   cargo build --release -p lightloom
#   mkdir -p .device && cp target/release/lightloom .device/ && echo /.device/ >> .git/info/exclude
#   and the Vulkan loader packages in .gl/ as the device tool's README says.
# Run there: carry [".device", ".gl"], command `bash tools/device/relight_check.sh`, timeout 480.
set -uo pipefail
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
if [ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ]; then
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
fi
out=${OUT:-/tmp}
nvidia-smi --query-gpu=name,driver_version --format=csv 2>&1 | tee "$out/relight_check.txt"
.device/lightloom bench --only default,synthetic --frames 5 2>&1 | tee -a "$out/relight_check.txt"
for size in "320 180" "1280 720"; do
    set -- $size
    for edit in "sky.rotation=40,0,0" "material.model=ggx --edit material.roughness=0.5 --edit material.f0=1 --edit material.specular=0.3,0.3,0.3" "sky.sun_elevation=25"; do
        echo "== ${1}x${2}, edit: $edit" | tee -a "$out/relight_check.txt"
        # shellcheck disable=SC2086
        .device/lightloom accuracy tests/projects/sharp_sun.ron --samples 16 --width "$1" --height "$2" --bands 6 \
            --wavelets 320 --adaptive 10 --square-lights 30 --sun separate --edit $edit 2>&1 | tee -a "$out/relight_check.txt"
    done
done
