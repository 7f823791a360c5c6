#!/usr/bin/env bash
# Frame and relight times of the viewport on a real GPU, for the workplace's device tool (a
# lent machine with an NVIDIA GPU; CI never runs this). It prints `lightloom bench`'s default
# and synthetic sections, where the wavelet modes' relight runs once as the CPU twin and once
# as the compute kernel (wavelet_relight.wgsl).
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
