"""The .ehm map file: versioned, checksummed, written atomically.

Layout (little-endian):
    8 bytes   magic b"EHMMAP\\r\\n"
    4 bytes   uint32 format version
    8 bytes   uint64 length of the JSON header
    header    UTF-8 JSON: config, dim, n_scans, bias state, random generator state (from
              version 4 on), and for each array (the clusters', the anchor layers', the
              sample memory's from version 5 on, the scans waiting for their batch from
              version 10 on, the sensor path from version 11 on) its name, dtype, shape and
              byte offset into the payload
    payload   the arrays' raw bytes, one after another
    4 bytes   uint32 CRC-32 of everything before it
"""

from __future__ import annotations

import json
import struct
import zlib
from os import PathLike

import numpy as np

from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.core.observations.memory import EvidenceMemory
from ehm.core.observations.samples import TrainingSamples
from ehm.core.search.anchors import AnchorLayers
from ehm.core.sensor.scan import Scan
from ehm.core.state import MapState
from ehm.errors import EhmError, FileReadError
from ehm.io.files import read_bytes, write_atomically

MAGIC = b"EHMMAP\r\n"
# Arrays of the anchor layers are stored beside the clusters' under names with this prefix.
ANCHOR_PREFIX = "anchor_"
MEMORY_PREFIX = "memory_"
WAITING_PREFIX = "waiting_"
SENSOR_PATH = "sensor_path"
# Version 6: every update rule learns the weights' precisions (the occupancy's std); files of
# older versions learned by SGD hold the prior's, so their std stays near the prior's until
# they learn more.
# Version 7 maps may take every kernel not zero at a point as its features (MapConfig.features
# 'support'); older files learned and answer with the nearest clusters ('nearest').
# Version 5 stores the sample memory; older files load with none.
# Version 4 stores the random generator's state and each weight's posterior precision;
# version 3 files load with a generator started afresh from the map's seed, and learn on by
# SGD as they did.
# Version 9 maps may gather small scans into batches (MapConfig.batch_rays); older files
# learned each scan as it came.
# Version 10 maps may limit the rays' range (MapConfig.min_range, max_range) and bound the
# free samples per ray (max_free_samples). Older files load with the defaults: no range limit,
# and the bound, which changes nothing for rays under 600 m. Version 10 files also hold the
# scans waiting for their batch; older ones learned them before saving.
# Version 11 maps keep the origin of every scan given (the sensor path); older files load
# with none.
# Version 12 maps may learn inside a box only (MapConfig.learn_box: the tiles of a TiledMap).
# Version 13 maps keep past evidence per cell (ehm.core.observations.memory,
# MapConfig.keep_evidence) where older ones kept samples (memory_per_cell, and samples_per_cell
# thinned them): their kept samples load as evidence, each weighing its cell's samples seen over
# those kept.
# Version 14 keeps the past evidence region by region, each entry's place in a byte an axis;
# version 13 files load their keys so, and their places to the nearest 1/255 of a cell.
# Version 15 flags each entry of the past evidence (ehm.core.observations.memory): formed part
# of a cluster, passed through by rays; older files load with none passed.
# Version 16 keeps time: the latest time stamp learned, when each cluster and each region of the
# past evidence last had evidence, and the time of each scan waiting for its batch (for
# MapConfig.forget_after); older files load with none.
# Version 17 maps may give occupied clusters kernels of their own span
# (MapConfig.occupied_length_scale); older files made them as wide as free ones, and load so.
# Version 18 maps may keep their clusters and memory relative to a point near their first
# sensor pose (HilbertMap.local_origin_, georeferenced data); older files keep the world
# origin, and load so.
# Version 19 maps read their log-odds calibrated (MapConfig.calibrate, the scale they read them
# times); older files read them raw, and load with calibrate off.
# Version 20 maps may hold coarse weights at or below 0 (MapConfig.coarse_free_only) and widen
# fine clusters where hits lie far apart (MapConfig.hits_per_radius); older files learned
# without either, and learn on so.
# Version 21 maps place hits' free samples clear of the range noise (MapConfig.noise_clearance);
# older files learned without, and learn on so.
# Version 22 maps cluster the samples behind hits apart from the hits and keep them in the past
# evidence as a kind of their own (MapConfig.cluster_behind_apart); older files kept them as
# hits, and learn on with both in one cluster.
# Version 23 maps start new clusters at the weight of their label (MapConfig.initial_weight);
# older files started them at 0, and learn on so.
FORMAT_VERSION = 23
OLDEST_READABLE_VERSION = 3
_PREAMBLE = struct.Struct("<8sIQ")
_CRC = struct.Struct("<I")


class MapFileError(FileReadError):
    """A file that is not a readable ehm map: foreign, truncated, corrupt or too new."""


def write_map(state: MapState, path: str | PathLike[str]) -> None:
    """Write a map's state to `path`: a temporary file in the same folder, then a rename, so an
    existing map survives a crash half-way."""
    write_atomically(path, map_bytes(state))


def map_bytes(state: MapState) -> bytes:
    """A map's state as the bytes of its file."""
    arrays = {name: np.ascontiguousarray(a) for name, a in state.clusters.arrays().items()}
    anchors = state.anchors
    for layer, (parents, coarse) in enumerate(zip(anchors.parents, anchors.coarse, strict=True)):
        arrays[f"{ANCHOR_PREFIX}parents_{layer}"] = parents
        arrays[f"{ANCHOR_PREFIX}coarse_{layer}"] = coarse
    for name, array in state.memory.arrays().items():
        arrays[f"{MEMORY_PREFIX}{name}"] = np.ascontiguousarray(array)
    if state.waiting:
        for name, array in _waiting_arrays(state.waiting).items():
            arrays[f"{WAITING_PREFIX}{name}"] = array
    if state.sensor_path is not None:
        arrays[SENSOR_PATH] = np.ascontiguousarray(state.sensor_path, dtype=np.float64)
    entries, offset = [], 0
    for name, array in arrays.items():
        dtype = array.dtype.newbyteorder("<")
        entries.append(
            {"name": name, "dtype": dtype.str, "shape": list(array.shape), "offset": offset}
        )
        offset += array.nbytes
    header = json.dumps(
        {
            "config": state.config.to_dict(),
            "dim": state.clusters.dim,
            "n_scans": state.n_scans,
            "bias_state": state.bias_state.tolist(),
            "rng_state": state.rng_state,
            "time": state.time,
            "local_origin": None if state.local_origin is None else state.local_origin.tolist(),
            "scale": state.scale,
            "arrays": entries,
        }
    ).encode()
    body = b"".join(
        [_PREAMBLE.pack(MAGIC, FORMAT_VERSION, len(header)), header]
        + [a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes() for a in arrays.values()]
    )
    return body + _CRC.pack(zlib.crc32(body))


def read_map(path: str | PathLike[str]) -> MapState:
    """Read the state of a map written by `write_map` (format versions 3 to 19); MapFileError
    names what is wrong otherwise."""
    return map_state_of_bytes(read_bytes(path), path)


def map_state_of_bytes(data: bytes, path: str | PathLike[str]) -> MapState:
    """The state of a map from the bytes of its file; MapFileError names `path` and what is
    wrong with them."""
    if len(data) < len(MAGIC) or data[: len(MAGIC)] != MAGIC:
        raise MapFileError(path, "not an ehm map file (unknown magic bytes)")
    if len(data) < _PREAMBLE.size + _CRC.size:
        raise MapFileError(path, f"truncated ({len(data)} bytes)")
    _, version, header_length = _PREAMBLE.unpack_from(data)
    if version < OLDEST_READABLE_VERSION:
        raise MapFileError(
            path,
            f"format version {version} is older than this ehm reads "
            f"({OLDEST_READABLE_VERSION} to {FORMAT_VERSION}); rebuild the map from its scans",
        )
    if version > FORMAT_VERSION:
        raise MapFileError(
            path, f"format version {version} is newer than this ehm reads ({FORMAT_VERSION})"
        )
    body, (stored_crc,) = data[: -_CRC.size], _CRC.unpack_from(data, len(data) - _CRC.size)
    try:
        header = json.loads(data[_PREAMBLE.size : _PREAMBLE.size + header_length])
        payload_start = _PREAMBLE.size + header_length
        expected = payload_start + sum(
            int(np.prod(e["shape"])) * np.dtype(e["dtype"]).itemsize for e in header["arrays"]
        )
    except (ValueError, KeyError, TypeError) as error:
        raise MapFileError(path, f"corrupt or truncated header ({error})") from error
    if len(body) < expected:
        raise MapFileError(path, f"truncated ({len(data)} bytes, expected {expected + 4})")
    if zlib.crc32(body) != stored_crc:
        raise MapFileError(path, "corrupt (checksum mismatch)")
    try:
        return _map_state(data, header, payload_start, version)
    except (EhmError, KeyError, TypeError, ValueError) as error:
        # A file whose checksum matches but whose content does not make a map: written by
        # something else, or edited and checksummed again.
        raise MapFileError(path, f"inconsistent content ({error})") from error


def _map_state(data: bytes, header: dict, payload_start: int, version: int) -> MapState:
    """The map state held by a checked file's header and payload."""
    arrays = {}
    for entry in header["arrays"]:
        dtype = np.dtype(entry["dtype"])
        count = int(np.prod(entry["shape"]))
        start = payload_start + entry["offset"]
        flat = np.frombuffer(data, dtype=dtype, count=count, offset=start)
        arrays[entry["name"]] = flat.reshape(entry["shape"]).astype(dtype.newbyteorder("="))
    n_layers = sum(name.startswith(f"{ANCHOR_PREFIX}parents_") for name in arrays)
    anchors = AnchorLayers(
        [arrays.pop(f"{ANCHOR_PREFIX}parents_{layer}") for layer in range(n_layers)],
        [arrays.pop(f"{ANCHOR_PREFIX}coarse_{layer}") for layer in range(n_layers)],
    )
    memory_arrays = {
        name.removeprefix(MEMORY_PREFIX): arrays.pop(name)
        for name in list(arrays)
        if name.startswith(MEMORY_PREFIX)
    }
    sensor_path = arrays.pop(SENSOR_PATH, None)
    waiting_arrays = {
        name.removeprefix(WAITING_PREFIX): arrays.pop(name)
        for name in list(arrays)
        if name.startswith(WAITING_PREFIX)
    }
    settings = header["config"]
    dim = header["dim"]
    kept = None
    if version < 13:
        kept, memory_arrays = _kept_samples(memory_arrays), {}
        settings = {k: v for k, v in settings.items() if k != "samples_per_cell"}
        settings["keep_evidence"] = settings.pop("memory_per_cell", 0) > 0
    if version < 9:
        # Maps before format 9 learned each scan as it came.
        settings = {**settings, "batch_rays": 0}
    if version < 7:
        # Maps before format 7 learned and answered with the nearest clusters' features.
        settings = {**settings, "features": "nearest"}
    if version < 5:
        # Maps of formats 3 and 4 learned without a sample memory, and go on so.
        settings = {**settings, "keep_evidence": False}
    if version == 3:
        # Format 3 maps learned by SGD and kept no posterior precisions.
        settings = {**settings, "update_rule": "sgd"}
        arrays["precision"] = np.full(len(arrays["weights"]), MapConfig().prior_precision)
    if version < 16:
        arrays["seen"] = np.full(len(arrays["weights"]), np.nan)
    if version < 17:
        length_scale = settings.get("length_scale", MapConfig().length_scale)
        settings = {**settings, "occupied_length_scale": length_scale}
    if version < 19:
        settings = {**settings, "calibrate": False}
    if version < 20:
        settings = {**settings, "coarse_free_only": False, "hits_per_radius": 0.0}
    if version < 21:
        settings = {**settings, "noise_clearance": 0.0}
    if version < 22:
        settings = {**settings, "cluster_behind_apart": False}
    if version < 23:
        settings = {**settings, "initial_weight": 0.0}
    config = MapConfig.from_dict(settings)
    if kept is not None:
        memory = EvidenceMemory.of_samples(dim, config, *kept)
    elif memory_arrays:
        memory = EvidenceMemory.from_arrays(dim, config, memory_arrays)
    else:
        memory = EvidenceMemory.of_config(dim, config)
    return MapState(
        config,
        ClusterSet(**arrays),
        anchors,
        np.array(header["bias_state"], dtype=np.float64),
        header["n_scans"],
        header.get("rng_state"),
        memory,
        _waiting_scans(waiting_arrays),
        sensor_path,
        header.get("time"),
        None if header.get("local_origin") is None else np.array(header["local_origin"], float),
        header.get("scale", 1.0),
    )


def _kept_samples(arrays: dict[str, np.ndarray]) -> tuple[TrainingSamples, np.ndarray] | None:
    """The samples a memory of a format before 13 kept, each weighing its cell's samples seen
    over those kept, and which formed part of a cluster; None for no memory."""
    if not arrays:
        return None
    kept = arrays["priority"] != np.uint32(2**32 - 1)  # the priority of an empty slot
    cell, _ = np.nonzero(kept)
    share = arrays["seen"] / np.maximum(arrays["filled"], 1)
    samples = TrainingSamples(
        arrays["points"][kept].astype(np.float64),
        arrays["occupied"][kept],
        arrays["at_surface"][cell],
        share[cell],
    )
    return samples, arrays.get("clustered", np.ones_like(kept))[kept]


def _waiting_arrays(scans: tuple[Scan, ...]) -> dict[str, np.ndarray]:
    """The scans waiting for their batch as five arrays: every ray's end point and hit flag,
    each scan's origin, ray count and time stamp (NaN: none)."""
    return {
        "points": np.concatenate([scan.points_world for scan in scans]),
        "hits": np.concatenate([scan.hit_mask for scan in scans]),
        "origins": np.stack([scan.origin for scan in scans]),
        "counts": np.array([len(scan) for scan in scans], dtype=np.int64),
        "times": np.array([np.nan if scan.time is None else scan.time for scan in scans]),
    }


def _waiting_scans(arrays: dict[str, np.ndarray]) -> tuple[Scan, ...]:
    if not arrays:
        return ()
    ends = np.cumsum(arrays["counts"])
    if ends[-1] != len(arrays["points"]) or len(arrays["hits"]) != len(arrays["points"]):
        raise ValueError("waiting scans' arrays differ in length")
    starts = ends - arrays["counts"]
    times = arrays.get("times", np.full(len(starts), np.nan))
    return tuple(
        Scan(arrays["points"][a:b], origin, arrays["hits"][a:b], None if np.isnan(t) else t)
        for a, b, origin, t in zip(starts, ends, arrays["origins"], times, strict=True)
    )
