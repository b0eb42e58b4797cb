#!/usr/bin/env python3
"""Reference values for tests/metrics/flip_reference_test.cpp, from NVIDIA's FLIP and scikit-image.

Not part of the build or the tests: run by hand, in a virtual environment outside the repository,
when a pinned value needs to be re-derived (the packages are never a dependency of the project):

    /usr/bin/python3 -m venv /tmp/flipvenv
    /tmp/flipvenv/bin/pip install flip-evaluator==1.7 scikit-image==0.26.0 numpy OpenEXR pillow
    /tmp/flipvenv/bin/python tests/metrics/data/flip_ssim_reference.py

The images are formulas of (x, y, c) on integers; every value is an 8-bit code or a dyadic rational,
so the C++ test (which writes the same formulas) and this script hold the same pixels exactly.
FLIP's own tool (`flip`, the package's command line) scores them, so the pooled statistics are
the ones its CSV reports; HDR pairs go through EXR files (the tool runs HDR-FLIP on EXR), LDR
pairs through 8-bit PNG files (LDR-FLIP, sRGB-decoded by the tool).
"""
import csv
import os
import subprocess
import sys
import tempfile

import numpy as np

W, H = 32, 24  # the FLIP pairs (an even pixel count)
SW, SH = 48, 40  # the SSIM pair (larger than the 11x11 window)


# ---- the formulas (tests/metrics/flip_reference_test.cpp writes the same) ------------------------
def hdr_reference(x, y, c):
    # The second term breaks ties, so that the two middle luminances differ (the median's definition shows).
    base = ((x * 5 + y * 3 + c * 7) % 16 + 1) / 16.0 + ((x * 11 + y * 29 + c * 5) % 97) / 2048.0
    return base * 2.0 ** (x // 8 + 2 * (y // 12))  # 1/16 .. 32 and a bit


def hdr_test(x, y, c):
    if x == 5 and y == 5:
        return 64.0  # a firefly
    d = (x * 7 + y * 11 + c * 3) % 5 - 2
    return hdr_reference(x, y, c) * (1.0 + d / 8.0)


def ldr_reference_code(x, y, c):
    return 40 + 160 * ((x // 4 + y // 4) % 2) + (x * 3 + y * 5 + c * 17) % 32


def ldr_test_code(x, y, c):
    return min(255, max(0, ldr_reference_code(x, y, c) + (x * 13 + y * 7 + c * 5) % 21 - 10))


def ssim_reference_code(x, y, c):
    return (x * 9 + y * 14 + c * 50 + 80 * ((x // 6 + y // 5) % 2)) % 256


def ssim_test_code(x, y, c):
    return min(255, max(0, ssim_reference_code(x, y, c) + (x * 29 + y * 31 + c * 7) % 41 - 20))


def image(f, w, h, dtype):
    return np.array([[[f(x, y, c) for c in range(3)] for x in range(w)] for y in range(h)], dtype=dtype)


# ---- NVIDIA's FLIP tool ---------------------------------------------------------------------------
def write_exr(path, rgb):
    import OpenEXR
    channels = {"RGB": rgb.astype(np.float32)}
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels) as f:
        f.write(path)


def write_png(path, codes):
    from PIL import Image
    Image.fromarray(codes.astype(np.uint8), "RGB").save(path)


# The package's command-line tool, installed beside this interpreter.
FLIP_TOOL = os.path.join(os.path.dirname(sys.executable), "flip")


def flip_tool(ref, test, tmp, name):
    csv_path = os.path.join(tmp, name + ".csv")
    out = subprocess.run([FLIP_TOOL, "-r", ref, "-t", test, "-ppd", "67", "-c", csv_path, "-nerm", "-nexm",
                          "-d", tmp], check=True, capture_output=True, text=True).stdout
    with open(csv_path) as f:
        row = list(csv.DictReader(f))[-1]
    return out, row


def main():
    import flip_evaluator
    import skimage
    from skimage.metrics import structural_similarity

    print(f"python {sys.version.split()[0]}, numpy {np.__version__}, scikit-image {skimage.__version__}")
    print(subprocess.run([FLIP_TOOL, "-h"], capture_output=True, text=True).stdout.splitlines()[0])
    with tempfile.TemporaryDirectory() as tmp:
        ref, test = image(hdr_reference, W, H, np.float32), image(hdr_test, W, H, np.float32)
        write_exr(os.path.join(tmp, "hdr_ref.exr"), ref)
        write_exr(os.path.join(tmp, "hdr_test.exr"), test)
        out, row = flip_tool(os.path.join(tmp, "hdr_ref.exr"), os.path.join(tmp, "hdr_test.exr"), tmp, "hdr")
        print("== HDR-FLIP (flip tool, EXR)\n" + out.strip())
        print("csv:", row)
        # The same pair through the Python API, for the exposure range it chose.
        _, mean, params = flip_evaluator.evaluate(ref, test, "HDR", applyMagma=False, parameters={"ppd": 67.0})
        print("api: mean", repr(mean), "parameters", params)

        rc, tc = image(ldr_reference_code, W, H, np.uint8), image(ldr_test_code, W, H, np.uint8)
        write_png(os.path.join(tmp, "ldr_ref.png"), rc)
        write_png(os.path.join(tmp, "ldr_test.png"), tc)
        out, row = flip_tool(os.path.join(tmp, "ldr_ref.png"), os.path.join(tmp, "ldr_test.png"), tmp, "ldr")
        print("== LDR-FLIP (flip tool, PNG)\n" + out.strip())
        print("csv:", row)
        # The same pair through the Python API (sRGB codes / 255, decoded by FLIP), for the mean's digits.
        _, mean, _ = flip_evaluator.evaluate((rc / 255.0).astype(np.float32), (tc / 255.0).astype(np.float32), "LDR",
                                             inputsRGB=True, applyMagma=False, parameters={"ppd": 67.0})
        print("api: mean", repr(mean))

    sr, st = image(ssim_reference_code, SW, SH, np.float64), image(ssim_test_code, SW, SH, np.float64)
    s = structural_similarity(st, sr, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                              data_range=255, channel_axis=2)
    print("== SSIM (skimage, gaussian_weights, sigma 1.5, population covariance, data_range 255)")
    print(repr(s))


if __name__ == "__main__":
    main()
