"""The warm server's warm-up: the preloaded libraries exercised once on synthetic data.

Sent to the warm server (:mod:`arenabench.eval.runs.warm_server`) as source, like the launcher, and
run there after the preloads and before the first run is forked. A fresh process pays, on a
script's first call into a library, for what the library sets up lazily and then keeps:
``argparse``'s lazy imports (``gettext``, ``locale``, ``shutil``) and translations lookup,
OpenCV's OpenCL probe, its image codecs' set-up, the allocator's growth to the sizes an image
pipeline uses (glibc raises its mmap threshold after the first free of a large block, so later
image-sized buffers come from the heap instead of new zero-filled mappings). Every forked run
would pay that again; done once in the server, each run inherits it.

Only libraries that the server has already imported from the Python installation are
exercised (:func:`warm_up` never imports anything a team wrote, nor anything new), on images
drawn here, never on a team's data or code. Nothing here changes what a run computes:

- OpenCV runs single-threaded meanwhile (``cv2.setNumThreads(1)``, then the former number
  again), so its worker threads are not started in the server (a forked run would inherit the
  pool without its threads and run single-threaded); a run starts its own pool as a fresh
  process does;
- no random generator is drawn from (OpenCV's ``theRNG``, ``random``, ``numpy.random``);
- nothing is written outside memory.

Standard library only at import (the server execs this source); ``numpy`` and ``cv2`` are
used where the server has them in :data:`sys.modules`.
"""

import sys


def _argparse():
    import argparse
    import io

    parser = argparse.ArgumentParser(description="arenabench warm-up")
    parser.add_argument("--image", required=True, help="an image")
    parser.add_argument("--n", type=int, default=1)
    parser.add_argument("--flag", action="store_true")
    parser.parse_args(["--image", "x.png", "--n", "2", "--flag"])
    parser.format_help()
    err, sys.stderr = sys.stderr, io.StringIO()
    try:
        parser.parse_args([])  # the error path: usage and message on (a captured) stderr
    except SystemExit:
        pass
    finally:
        sys.stderr = err


def _numpy(np):
    a = np.arange(4096, dtype=np.float64).reshape(64, 64)
    b = (a * 2.0 + 1.0) / 3.0
    np.sqrt(b).sum()
    np.sort(b, axis=None)
    np.concatenate([a, b]).astype(np.float32).mean()
    np.float32([[0, 0], [1, 0], [1, 1], [0, 1]])
    np.array([1.5, 2.5]).tolist()


def _scene(np, cv2, size):
    """A ``size`` x ``size`` BGR image: light floor, dark boxes, an ArUco marker per corner
    (DICT_4X4_250 ids 80, 85, 90, 95, as on the competition arena) where ``cv2.aruco`` has them."""
    image = np.full((size, size, 3), 205, np.uint8)
    for i in range(6):
        x, y = 150 + 120 * i, 200 + 90 * (i % 3)
        cv2.rectangle(image, (x, y), (x + 70, y + 110), (40, 50, 60), -1)
    aruco = getattr(cv2, "aruco", None)
    if aruco is not None and hasattr(aruco, "generateImageMarker"):
        dictionary = aruco.getPredefinedDictionary(aruco.DICT_4X4_250)
        side, pad = size // 10, size // 40
        spots = ((pad, pad), (size - pad - side, pad), (size - pad - side, size - pad - side),
                 (pad, size - pad - side))
        for i, marker_id in enumerate((80, 85, 90, 95)):
            x, y = spots[i]
            marker = aruco.generateImageMarker(dictionary, marker_id, side)
            image[y:y + side, x:x + side] = marker[:, :, None]
    return image


def _cv2(np, cv2):
    # image-sized buffers (1000 x 1000) where the allocator's growth matters, small ones
    # where only a set-up does (PNG codec, marker detection: the costly calls)
    image = _scene(np, cv2, 1000)
    ok, data = cv2.imencode(".jpg", image)
    if ok:
        image = cv2.imdecode(data, cv2.IMREAD_COLOR)
        cv2.imdecode(data, cv2.IMREAD_GRAYSCALE)
    ok, data = cv2.imencode(".png", image[:200, :200])
    if ok:
        cv2.imdecode(data, cv2.IMREAD_COLOR)
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    aruco = getattr(cv2, "aruco", None)
    if aruco is not None and hasattr(aruco, "ArucoDetector"):
        for name in ("DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000"):
            detector = aruco.ArucoDetector(aruco.getPredefinedDictionary(getattr(aruco, name)),
                                           aruco.DetectorParameters())
        detector.detectMarkers(cv2.resize(grey, (400, 400), interpolation=cv2.INTER_AREA))
    src = np.float32([[100, 100], [900, 120], [880, 900], [90, 880]])
    dst = np.float32([[0, 0], [1000, 0], [1000, 1000], [0, 1000]])
    warped = cv2.warpPerspective(image, cv2.getPerspectiveTransform(src, dst), (1000, 1000))
    blurred = cv2.GaussianBlur(cv2.cvtColor(warped, cv2.COLOR_BGR2GRAY), (5, 5), 0)
    _, mask = cv2.threshold(blurred, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
    cv2.threshold(blurred, 127, 255, cv2.THRESH_BINARY)
    cv2.inRange(image, (0, 0, 0), (100, 100, 100))
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    for contour in contours:
        cv2.contourArea(contour)
        cv2.boundingRect(contour)


def warm_up(modules=None):
    """Exercise ``argparse``, ``numpy`` and ``cv2`` where they are in ``modules`` (default
    :data:`sys.modules`); each step on its own, a failing one skipped.

    Returns
    -------
    list of str
        The steps that ran to the end.
    """
    modules = sys.modules if modules is None else modules
    done = []
    np, cv2 = modules.get("numpy"), modules.get("cv2")
    steps = []
    if "argparse" in modules:
        steps.append(("argparse", _argparse))
    if np is not None:
        steps.append(("numpy", lambda: _numpy(np)))
    if np is not None and cv2 is not None and hasattr(cv2, "setNumThreads"):
        steps.append(("cv2", lambda: _cv2_single_threaded(np, cv2)))
    for name, step in steps:
        try:
            step()
        except Exception:  # a library without what a step uses: that step is skipped
            continue
        done.append(name)
    return done


def _cv2_single_threaded(np, cv2):
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        if hasattr(cv2, "ocl"):
            cv2.ocl.haveOpenCL()
            cv2.ocl.useOpenCL()
        _cv2(np, cv2)
    finally:
        cv2.setNumThreads(threads)
