"""Input and output: images, their EXIF, calibration files, results and data sets.

- :mod:`scene3D.io.images`: images at the working size (size from the header, reduced
  JPEG decoding, streaming);
- :mod:`scene3D.io.halving`: the book's size rule and halving by area averaging;
- :mod:`scene3D.io.image_folders`: the images of a folder or a glob;
- :mod:`scene3D.io.image_integrity`: truncated and damaged JPEG, PNG and TIFF files found
  before decoding;
- :mod:`scene3D.io.exif`: the EXIF values that describe a photo's camera (Pillow);
- :mod:`scene3D.io.calibration`: the calibration file (OpenCV FileStorage);
- :mod:`scene3D.io.atomic`: atomic writes, a block of files all or none;
- :mod:`scene3D.io.ply`: PLY point clouds and meshes;
- :mod:`scene3D.io.export`: JSON summaries, figures, PNG images (and the first COLMAP
  writer, deprecated for :mod:`scene3D.io.colmap`'s), the names of the two above too;
- :mod:`scene3D.io.colmap`: COLMAP text models read and written in scene3D's conventions,
  at the photos' size, and a model of either form read;
- :mod:`scene3D.io.colmap_binary`: COLMAP binary models read and written;
- :mod:`scene3D.io.nerfstudio`: nerfstudio's ``transforms.json`` (NeRF and splatting);
- :mod:`scene3D.io.undistorted`: a model's images undistorted, and their pinhole model;
- :mod:`scene3D.io.datasets`: the fountain-P11 download and Strecha cameras.
"""

from .calibration import (
    CALIBRATION_SUFFIXES,
    MAX_IMAGE_SIDE_PX,
    CameraCalibration,
    load_calibration,
    save_calibration,
)
from .colmap import (
    CAMERA_MODELS,
    ColmapCamera,
    ColmapFormatError,
    ColmapModel,
    cameras_json,
    colmap_model_from_views,
    colmap_text,
    model_for_photos,
    read_colmap_model,
    read_colmap_text,
    write_colmap_text,
)
from .colmap_binary import colmap_binary, read_colmap_binary, write_colmap_binary
from .datasets import (
    BOOK_PAIR,
    FOUNTAIN_P11,
    FOUNTAIN_P11_SHA256,
    FOUNTAIN_P11_URL,
    ROTATION_TOLERANCE,
    StrechaCamera,
    StrechaScene,
    default_cache_dir,
    default_data_root,
    fetch_fountain_p11,
    read_strecha_camera,
    read_strecha_scene,
    relative_pose,
    sha256_of,
    strecha_views,
)
from .exif import read_camera_prior, read_exif
from .export import (
    all_or_nothing,
    atomic_write_bytes,
    atomic_write_pieces,
    check_target,
    colmap_image_name,
    colmap_text_files,
    place_file,
    ply_bytes,
    read_ply,
    save_figure,
    write_files,
    write_json,
    write_ply,
    write_text_files,
    written_bytes,
)
from .image_integrity import intact_image_data, jpeg_cut_short
from .images import (
    BOOK_MAX_WIDTH_PX,
    IMAGE_SUFFIXES,
    ImageSource,
    bgr_order,
    check_image_file,
    folder_images,
    glob_files,
    glob_patterns,
    halve,
    halving_levels,
    header_size,
    image_size,
    is_folder_image,
    is_heif,
    iter_working_images,
    load_bgr,
    load_working_image,
    load_working_images,
    read_image,
    read_image_size,
    refuse_single_path,
    register_heif_opener,
    source_label,
    to_bgr8,
)
from .nerfstudio import camera_to_world_opengl, nerfstudio_transforms, write_nerfstudio

__all__ = [
    "BOOK_MAX_WIDTH_PX", "BOOK_PAIR", "CALIBRATION_SUFFIXES", "CAMERA_MODELS",
    "CameraCalibration", "ColmapCamera", "ColmapFormatError", "ColmapModel", "FOUNTAIN_P11",
    "FOUNTAIN_P11_SHA256", "FOUNTAIN_P11_URL", "IMAGE_SUFFIXES", "ImageSource",
    "MAX_IMAGE_SIDE_PX", "ROTATION_TOLERANCE", "StrechaCamera", "StrechaScene",
    "all_or_nothing", "bgr_order", "atomic_write_bytes", "atomic_write_pieces",
    "camera_to_world_opengl", "cameras_json", "check_image_file", "colmap_binary",
    "check_target", "colmap_image_name", "colmap_model_from_views", "colmap_text",
    "colmap_text_files", "default_cache_dir", "default_data_root", "fetch_fountain_p11",
    "folder_images", "glob_files", "glob_patterns", "halve", "halving_levels", "header_size",
    "image_size", "intact_image_data", "is_folder_image", "is_heif", "iter_working_images",
    "jpeg_cut_short", "load_bgr", "load_calibration", "load_working_image",
    "load_working_images", "model_for_photos", "nerfstudio_transforms", "place_file",
    "ply_bytes", "read_camera_prior", "read_colmap_binary", "read_colmap_model",
    "read_colmap_text", "read_exif", "read_image", "read_image_size", "read_ply",
    "read_strecha_camera", "read_strecha_scene", "refuse_single_path", "register_heif_opener",
    "relative_pose", "save_calibration", "save_figure", "sha256_of", "source_label",
    "strecha_views", "to_bgr8", "write_colmap_binary", "write_colmap_text", "write_json",
    "write_nerfstudio", "write_files", "write_ply", "write_text_files", "written_bytes",
]
