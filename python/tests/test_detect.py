"""twincell.detect: the shipped detector on rendered frames, against their ground truth and
against `twincell detect`; bad images raise, naming the argument."""

import numpy as np
import pytest

import twincell
from conftest import run_cli


def iou(a, b):
    iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    area = lambda r: (r[2] - r[0]) * (r[3] - r[1])
    return iw * ih / (area(a) + area(b) - iw * ih)


def test_every_object_of_a_rendered_frame_is_found_as_a_tube_or_foreign(shots):
    for shot in shots:
        found = twincell.detect(shot.image)
        for truth in shot.objects:
            x0, y0, x1, y1 = truth["bbox_px"]
            edges = [x0, y0, x1 + 1, y1 + 1]
            best = max(found, key=lambda d: iou(d["box"], edges), default=None)
            assert best is not None, f"{shot.dir}: nothing found"
            assert iou(best["box"], edges) > 0.6, (shot.dir, truth, best)
            # The shipped detector finds tubes and foreign objects; the truth names the type.
            expected = "foreign" if truth["class"] == "bottle" else "tube"
            assert best["class"] == expected, (shot.dir, truth, best)
            assert 0.0 < best["score"] <= 1.0


def test_the_same_detections_as_the_command_line(shots, twincell_bin):
    for shot in shots:
        cli = run_cli(twincell_bin, "detect", shot.png, "--json")["images"][0]["detections"]
        ours = twincell.detect(shot.image)
        assert [d["class"] for d in ours] == [d["class"] for d in cli]
        for a, b in zip(ours, cli):
            assert a["score"] == pytest.approx(b["score"], abs=1e-6)
            assert a["box"] == pytest.approx(b["box"], abs=1e-3)


def test_any_memory_layout_gives_the_same_answer(shots):
    image = shots[0].image
    # A Fortran-ordered copy and a view with negative strides, flipped back.
    fortran = np.asfortranarray(image)
    flipped_view = image[::-1][::-1]
    expected = twincell.detect(image)
    assert twincell.detect(fortran) == expected
    assert twincell.detect(flipped_view) == expected


@pytest.mark.parametrize(
    "bad, error, words",
    [
        (np.zeros((48, 64, 3), dtype=np.float32), TypeError, "uint8"),
        (np.zeros((48, 64), dtype=np.uint8), ValueError, "H x W x 3"),
        (np.zeros((48, 64, 4), dtype=np.uint8), ValueError, "H x W x 3"),
        (np.zeros((0, 64, 3), dtype=np.uint8), ValueError, "empty"),
        ([[[0, 0, 0]]], TypeError, "uint8"),
        (None, TypeError, "uint8"),
    ],
)
def test_a_bad_image_raises_naming_the_argument(bad, error, words):
    with pytest.raises(error) as caught:
        twincell.detect(bad)
    message = str(caught.value)
    assert message.startswith("image:"), message
    assert words in message, message


def test_a_missing_model_file_raises_naming_it(tmp_path):
    image = np.zeros((48, 64, 3), dtype=np.uint8)
    with pytest.raises(ValueError, match=r"^model:"):
        twincell.detect(image, model=tmp_path / "none.onnx")


def test_threads_share_the_detector_and_get_the_same_answers(shots):
    """The detector runs without the GIL; threads calling it at once must neither deadlock
    nor mix up their frames."""
    import threading

    images = [shot.image for shot in shots]
    expected = [twincell.detect(image) for image in images]
    results = {}

    def work(worker):
        for round_ in range(2):
            for i, image in enumerate(images):
                results[(worker, round_, i)] = twincell.detect(image)

    # Daemon threads, so that a deadlock fails the test instead of hanging the interpreter.
    threads = [threading.Thread(target=work, args=(w,), daemon=True) for w in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
        assert not t.is_alive(), "a thread calling detect did not finish"
    assert len(results) == 3 * 2 * len(images)
    for (_, _, i), found in results.items():
        assert found == expected[i]
