#!/usr/bin/env python3
"""Converts VGG-LPIPS weights from PyTorch checkpoints into one flat binary a C++ loader reads without PyTorch.

Usage: convert_lpips_weights.py VGG16_PTH LPIPS_VGG_PTH OUT_BIN
  VGG16_PTH      torchvision's ImageNet VGG16 (vgg16-397923af.pth): the conv trunk, keys features.N.weight/bias
  LPIPS_VGG_PTH  LPIPS v0.1 linear heads (lpips/weights/v0.1/vgg.pth): keys lin0..lin4.model.1.weight

Reads both PyTorch serialisations with the standard library only: the zip format (torch >= 1.6: data.pkl plus
one raw file per storage) and the legacy format (five pickles followed by raw storages). Only tensors it needs
are read; anything else in the pickles (classes, hooks) is refused unless listed below.

Output format (all little-endian), "watergs LPIPS-VGG weights v1":
  char[8]  magic "WGLPIPS1"
  uint32   tensor count
  per tensor: uint32 name length, name (UTF-8, no terminator), uint32 ndim, int64 dims[ndim],
              float32 values[product(dims)] in C order (PyTorch's layout: conv weights are OIHW)
  uint32   CRC-32 (zlib) of every byte before it
Tensors, in this order:
  scaling.shift [3] = (-0.030, -0.088, -0.188), scaling.scale [3] = (0.458, 0.448, 0.450)
      LPIPS input: x in [-1, 1] RGB, x' = (x - shift) / scale per channel
  features.{0,2,5,7,10,12,14,17,19,21,24,26,28}.weight [Cout, Cin, 3, 3] and .bias [Cout]
      VGG16 convs (3x3, stride 1, padding 1, each followed by ReLU; 2x2 max-pool stride 2 after 2, 4, 7, 10 convs);
      LPIPS taps relu1_2, relu2_2, relu3_3, relu4_3, relu5_3 (after convs 2, 4, 7, 10, 13)
  lin{0..4}.weight [1, C, 1, 1] with C = 64, 128, 256, 512, 512
      LPIPS = sum_l mean_hw( sum_c w_lc (f0_lchw / |f0_lhw| - f1_lchw / |f1_lhw|)^2 ), |.| the channel L2 norm
      (+1e-10 under the division)
"""
import array
import collections
import os
import pickle
import struct
import sys
import zipfile
import zlib

DTYPES = {"FloatStorage": ("f", 4), "DoubleStorage": ("d", 8)}
LEGACY_MAGIC = 0x1950A86A20F9469CFC6C
VGG_CONV_INDICES = (0, 2, 5, 7, 10, 12, 14, 17, 19, 21, 24, 26, 28)
LPIPS_CHANNELS = (64, 128, 256, 512, 512)


class StorageType:
    def __init__(self, name):
        if name not in DTYPES:
            raise ValueError("unsupported storage type torch.%s" % name)
        self.name = name


class Storage:
    def __init__(self, storage_type, key, numel):
        self.storage_type, self.key, self.numel = storage_type, str(key), numel
        self.data = None  # bytes, filled after unpickling


class Tensor:
    def __init__(self, storage, offset, size, stride):
        self.storage, self.offset, self.size, self.stride = storage, offset, tuple(size), tuple(stride)

    def values(self):
        """The tensor's elements in C order as float32 (array('f'))."""
        code, width = DTYPES[self.storage.storage_type.name]
        flat = array.array(code)
        flat.frombytes(self.storage.data)
        if sys.byteorder != "little":
            flat.byteswap()
        count = 1
        for dim in self.size:
            count *= dim
        contiguous, expected = True, 1
        for dim, stride in zip(reversed(self.size), reversed(self.stride)):
            if dim > 1 and stride != expected:
                contiguous = False
            expected *= dim
        if contiguous:
            picked = flat[self.offset:self.offset + count]
        else:
            picked = [flat[self.offset + sum(i * s for i, s in zip(index, self.stride))]
                      for index in _indices(self.size)]
        if len(picked) != count:
            raise ValueError("tensor runs past its storage (%d of %d values)" % (len(picked), count))
        return array.array("f", picked)


def _indices(size):
    if not size:
        yield ()
        return
    for first in range(size[0]):
        for rest in _indices(size[1:]):
            yield (first,) + rest


def _rebuild_tensor(storage, offset, size, stride, *unused):
    return Tensor(storage, offset, size, stride)


def _rebuild_parameter(data, *unused):
    return data


class CheckpointUnpickler(pickle.Unpickler):
    ALLOWED = {
        ("collections", "OrderedDict"): collections.OrderedDict,
        ("torch._utils", "_rebuild_tensor_v2"): _rebuild_tensor,
        ("torch._utils", "_rebuild_tensor"): _rebuild_tensor,
        ("torch._utils", "_rebuild_parameter"): _rebuild_parameter,
    }

    def __init__(self, file):
        super().__init__(file)
        self.storages = collections.OrderedDict()

    def find_class(self, module, name):
        if (module, name) in self.ALLOWED:
            return self.ALLOWED[(module, name)]
        if module == "torch" and name.endswith("Storage"):
            return StorageType(name)
        raise pickle.UnpicklingError("checkpoint refers to %s.%s, which this reader does not load" % (module, name))

    def persistent_load(self, pid):
        if not isinstance(pid, tuple) or pid[0] != "storage":
            raise pickle.UnpicklingError("unknown persistent id %r" % (pid,))
        storage_type, key, numel = pid[1], pid[2], pid[4]
        if len(pid) > 5 and pid[5] is not None:
            raise pickle.UnpicklingError("storage views are not supported")
        if str(key) not in self.storages:
            self.storages[str(key)] = Storage(storage_type, key, numel)
        return self.storages[str(key)]


def load_state_dict(path):
    """Flat dict name -> Tensor of a PyTorch checkpoint (zip or legacy format)."""
    if zipfile.is_zipfile(path):
        with zipfile.ZipFile(path) as archive:
            pickles = [n for n in archive.namelist() if n.endswith("/data.pkl") or n == "data.pkl"]
            if len(pickles) != 1:
                raise ValueError("%s: zip checkpoint without a single data.pkl" % path)
            prefix = pickles[0][:-len("data.pkl")]
            with archive.open(pickles[0]) as f:
                unpickler = CheckpointUnpickler(f)
                result = unpickler.load()
            for key, storage in unpickler.storages.items():
                storage.data = archive.read(prefix + "data/" + key)
    else:
        with open(path, "rb") as f:
            if pickle.load(f) != LEGACY_MAGIC:
                raise ValueError("%s: neither a zip nor a legacy PyTorch checkpoint" % path)
            pickle.load(f)  # protocol version
            pickle.load(f)  # system info
            unpickler = CheckpointUnpickler(f)
            result = unpickler.load()
            keys = pickle.load(f)
            for key in keys:
                storage = unpickler.storages.get(str(key))
                (numel,) = struct.unpack("<q", f.read(8))
                width = DTYPES[storage.storage_type.name][1] if storage else 4
                data = f.read(numel * width)
                if len(data) != numel * width:
                    raise ValueError("%s: truncated storage %s" % (path, key))
                if storage:
                    storage.data = data
    if isinstance(result, dict) and "state_dict" in result:
        result = result["state_dict"]
    if not isinstance(result, dict):
        raise ValueError("%s: checkpoint is not a state dict" % path)
    return {name.replace("module.", "", 1) if name.startswith("module.") else name: value
            for name, value in result.items()}


def expect(tensors, name, shape, path):
    if name not in tensors:
        raise ValueError("%s: missing tensor %s" % (path, name))
    if tensors[name].size != tuple(shape):
        raise ValueError("%s: %s has shape %s, expected %s" % (path, name, tensors[name].size, tuple(shape)))
    return tensors[name].values()


def collect(vgg_path, lpips_path):
    vgg = load_state_dict(vgg_path)
    lpips = load_state_dict(lpips_path)
    out = [("scaling.shift", (3,), array.array("f", [-0.030, -0.088, -0.188])),
           ("scaling.scale", (3,), array.array("f", [0.458, 0.448, 0.450]))]
    in_channels = 3
    widths = (64, 64, 128, 128, 256, 256, 256, 512, 512, 512, 512, 512, 512)
    for index, width in zip(VGG_CONV_INDICES, widths):
        weight_shape = (width, in_channels, 3, 3)
        out.append(("features.%d.weight" % index, weight_shape,
                    expect(vgg, "features.%d.weight" % index, weight_shape, vgg_path)))
        out.append(("features.%d.bias" % index, (width,), expect(vgg, "features.%d.bias" % index, (width,), vgg_path)))
        in_channels = width
    for layer, channels in enumerate(LPIPS_CHANNELS):
        shape = (1, channels, 1, 1)
        # Saved from nn.Sequential(Dropout, Conv2d): the conv is entry 1 (entry 0 without dropout).
        names = ["lin%d.model.1.weight" % layer, "lin%d.model.0.weight" % layer]
        name = next((n for n in names if n in lpips), names[0])
        out.append(("lin%d.weight" % layer, shape, expect(lpips, name, shape, lpips_path)))
    return out


def write(out_path, tensors):
    blob = bytearray(b"WGLPIPS1")
    blob += struct.pack("<I", len(tensors))
    for name, shape, values in tensors:
        encoded = name.encode()
        blob += struct.pack("<I", len(encoded)) + encoded
        blob += struct.pack("<I", len(shape)) + struct.pack("<%dq" % len(shape), *shape)
        if sys.byteorder != "little":
            values = array.array("f", values)
            values.byteswap()
        blob += values.tobytes()
    blob += struct.pack("<I", zlib.crc32(blob) & 0xFFFFFFFF)
    with open(out_path + ".tmp", "wb") as f:
        f.write(blob)
    os.replace(out_path + ".tmp", out_path)
    return len(blob)


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    try:
        tensors = collect(sys.argv[1], sys.argv[2])
    except (ValueError, pickle.UnpicklingError, OSError, EOFError, KeyError, struct.error) as error:
        sys.exit("convert_lpips_weights: %s" % error)
    size = write(sys.argv[3], tensors)
    print("convert_lpips_weights: wrote %s (%d tensors, %d bytes)" % (sys.argv[3], len(tensors), size))


if __name__ == "__main__":
    main()
