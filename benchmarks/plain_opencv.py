"""The hand-written plain-OpenCV two-view script that chapter4.py is timed against.

What a user would write without scene3D: read, pyrDown to the book's size, SIFT,
ratio test, essential matrix (USAC MAGSAC), recoverPose, triangulate. Usage:

    python benchmarks/plain_opencv.py IMG1 IMG2 K.txt
"""

import argparse
import sys

import cv2
import numpy as np


def reconstruct(path1: str, path2: str, k_path: str) -> None:
    """The script's work: prints R, t and the number of triangulated points."""
    img1 = cv2.imread(path1, cv2.IMREAD_COLOR)
    img2 = cv2.imread(path2, cv2.IMREAD_COLOR)
    K = np.loadtxt(k_path)
    while img1.shape[1] > 1200:
        img1, img2 = cv2.pyrDown(img1), cv2.pyrDown(img2)
        K = np.diag([0.5, 0.5, 1.0]) @ K
    sift = cv2.SIFT_create()
    kp1, d1 = sift.detectAndCompute(cv2.cvtColor(img1, cv2.COLOR_BGR2GRAY), None)
    kp2, d2 = sift.detectAndCompute(cv2.cvtColor(img2, cv2.COLOR_BGR2GRAY), None)
    good = [m for m, n in cv2.BFMatcher().knnMatch(d1, d2, k=2) if m.distance < 0.8 * n.distance]
    p1 = np.float64([kp1[m.queryIdx].pt for m in good])
    p2 = np.float64([kp2[m.trainIdx].pt for m in good])
    E, mask = cv2.findEssentialMat(p1, p2, K, cv2.USAC_MAGSAC, 0.999, 1.0)
    _, R, t, mask = cv2.recoverPose(E, p1, p2, K, mask=mask)
    inl = mask.ravel() > 0
    P1 = K @ np.hstack([np.eye(3), np.zeros((3, 1))])
    P2 = K @ np.hstack([R, t])
    X = cv2.triangulatePoints(P1, P2, p1[inl].T, p2[inl].T)
    print(R, t.ravel(), X.shape[1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("image1", metavar="IMG1", help="the first photo")
    parser.add_argument("image2", metavar="IMG2", help="the second photo")
    parser.add_argument("k_path", metavar="K.txt",
                        help="the camera matrix at the photos' size, 3 rows of 3 numbers "
                             "(numpy.loadtxt)")
    args = parser.parse_args(argv)
    reconstruct(args.image1, args.image2, args.k_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
