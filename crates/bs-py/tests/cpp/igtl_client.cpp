// An OpenIGTLink client built on the reference C++ library (Debian's libopenigtlink-dev
// 1.11; .ci/python.sh builds it), for test_cpp_client.py: it sends one message made by the
// library and writes every reply the server sends back, unpacked by the library with its
// CRC check, into OUTDIR, until REPLIES messages have come (or the server closes).
//
//   igtl_client HOST PORT OUTDIR REPLIES KIND DEVICE [ARGS...]
//     KIND string    ARGS: TEXT             STRING (US-ASCII)
//     KIND points    ARGS: FILE.csv         POINT, rows name,x,y,z
//     KIND polydata  ARGS: POINTS.csv TRIS.csv   POLYDATA of triangle polygons
//     KIND status    ARGS: (none)           STATUS OK, as 3D Slicer sends on connecting
//     KIND get       ARGS: (none)           GET_IMAGE (a query; header only)
//     KIND landmarks ARGS: PRE.csv INTRA.csv   POINT PreopLandmarks, then POINT
//                                              IntraopLandmarks (DEVICE unused)
//
// Per reply k (from 0): k-DEVICE.txt: its type, device, whether the CRC held, and the
// fields (IMAGE: size, components, scalar type, endianness, frame, spacing and the 4x4
// matrix as the library reads them: unit directions and the centre; POLYDATA: points and polygons; STRING: the text); IMAGE also writes
// k-DEVICE.raw, the voxels as the library holds them.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "igtlClientSocket.h"
#include "igtlImageMessage.h"
#include "igtlPointMessage.h"
#include "igtlPolyDataMessage.h"
#include "igtlStatusMessage.h"
#include "igtlStringMessage.h"

static std::vector<std::vector<std::string>> rows(const char* path) {
  std::ifstream f(path);
  std::vector<std::vector<std::string>> out;
  std::string line;
  while (std::getline(f, line)) {
    std::vector<std::string> cells;
    std::stringstream s(line);
    std::string c;
    while (std::getline(s, c, ',')) cells.push_back(c);
    if (!cells.empty()) out.push_back(cells);
  }
  return out;
}

static igtl::MessageBase::Pointer message(const std::string& kind, const char* device, char** args) {
  if (kind == "string") {
    igtl::StringMessage::Pointer m = igtl::StringMessage::New();
    m->SetDeviceName(device);
    m->SetString(args[0]);
    return igtl::MessageBase::Pointer(m);
  }
  if (kind == "points") {
    igtl::PointMessage::Pointer m = igtl::PointMessage::New();
    m->SetDeviceName(device);
    for (auto& r : rows(args[0])) {
      igtl::PointElement::Pointer e = igtl::PointElement::New();
      e->SetName(r[0].c_str());
      e->SetPosition(std::stof(r[1]), std::stof(r[2]), std::stof(r[3]));
      m->AddPointElement(e);
    }
    return igtl::MessageBase::Pointer(m);
  }
  if (kind == "polydata") {
    igtl::PolyDataMessage::Pointer m = igtl::PolyDataMessage::New();
    m->SetDeviceName(device);
    igtl::PolyDataPointArray::Pointer p = igtl::PolyDataPointArray::New();
    for (auto& r : rows(args[0])) p->AddPoint(std::stof(r[0]), std::stof(r[1]), std::stof(r[2]));
    igtl::PolyDataCellArray::Pointer t = igtl::PolyDataCellArray::New();
    for (auto& r : rows(args[1])) {
      igtlUint32 c[3] = {(igtlUint32)std::stoul(r[0]), (igtlUint32)std::stoul(r[1]), (igtlUint32)std::stoul(r[2])};
      t->AddCell(3, c);
    }
    m->SetPoints(p);
    m->SetPolygons(t);
    return igtl::MessageBase::Pointer(m);
  }
  if (kind == "status") {
    igtl::StatusMessage::Pointer m = igtl::StatusMessage::New();
    m->SetDeviceName(device);
    m->SetCode(igtl::StatusMessage::STATUS_OK);
    m->SetStatusString("connected");
    return igtl::MessageBase::Pointer(m);
  }
  if (kind == "get") {
    igtl::GetImageMessage::Pointer m = igtl::GetImageMessage::New();
    m->SetDeviceName(device);
    return igtl::MessageBase::Pointer(m);
  }
  std::cerr << "unknown kind " << kind << "\n";
  std::exit(2);
}

// Receives the body of the message `h` into `m`; whether the CRC held.
template <class M>
static bool receive(igtl::ClientSocket* s, igtl::MessageHeader* h, M m) {
  m->SetMessageHeader(h);
  m->AllocatePack();
  s->Receive(m->GetPackBodyPointer(), m->GetPackBodySize());
  return (m->Unpack(1) & igtl::MessageHeader::UNPACK_BODY) != 0;
}

static void image(std::ostream& o, const std::string& base, igtl::ImageMessage* m) {
  int d[3];
  m->GetDimensions(d);
  igtl::Matrix4x4 a;
  m->GetMatrix(a);
  float sp[3];
  m->GetSpacing(sp);
  o << std::setprecision(9);
  o << "spacing " << sp[0] << " " << sp[1] << " " << sp[2] << "\n";
  o << "size " << d[0] << " " << d[1] << " " << d[2] << "\ncomponents " << m->GetNumComponents()
    << "\nscalar " << m->GetScalarType() << "\nendian " << m->GetEndian() << "\nframe "
    << m->GetCoordinateSystem() << "\nmatrix";
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) o << " " << a[r][c];
  o << "\n";
  std::ofstream raw(base + ".raw", std::ios::binary);
  raw.write(static_cast<const char*>(m->GetScalarPointer()), m->GetImageSize());
}

int main(int argc, char** argv) {
  if (argc < 7) {
    std::cerr << "usage: igtl_client HOST PORT OUTDIR REPLIES KIND DEVICE [ARGS...]\n";
    return 2;
  }
  igtl::ClientSocket::Pointer s = igtl::ClientSocket::New();
  if (s->ConnectToServer(argv[1], std::atoi(argv[2])) != 0) {
    std::cerr << "cannot connect to " << argv[1] << ":" << argv[2] << "\n";
    return 1;
  }
  std::string out = argv[3];
  int replies = std::atoi(argv[4]);
  std::vector<igtl::MessageBase::Pointer> sent;
  if (std::string(argv[5]) == "landmarks") {
    sent.push_back(message("points", "PreopLandmarks", argv + 7));
    sent.push_back(message("points", "IntraopLandmarks", argv + 8));
  } else {
    sent.push_back(message(argv[5], argv[6], argv + 7));
  }
  for (auto& m : sent) {
    m->Pack();
    s->Send(m->GetPackPointer(), m->GetPackSize());
  }
  for (int k = 0; k < replies; ++k) {
    igtl::MessageHeader::Pointer h = igtl::MessageHeader::New();
    h->InitPack();
    if (s->Receive(h->GetPackPointer(), h->GetPackSize()) != h->GetPackSize()) break;
    h->Unpack();
    std::string type = h->GetDeviceType(), device = h->GetDeviceName();
    std::string base = out + "/" + std::to_string(k) + "-" + device;
    std::ofstream o(base + ".txt");
    o << "type " << type << "\ndevice " << device << "\n";
    bool crc = false;
    if (type == "IMAGE") {
      igtl::ImageMessage::Pointer i = igtl::ImageMessage::New();
      crc = receive(s, h, i);
      if (crc) image(o, base, i);
    } else if (type == "POLYDATA") {
      igtl::PolyDataMessage::Pointer p = igtl::PolyDataMessage::New();
      crc = receive(s, h, p);
      if (crc) {
        o << "points " << p->GetPoints()->GetNumberOfPoints() << "\npolygons "
          << p->GetPolygons()->GetNumberOfCells() << "\n";
        std::ofstream pts(base + ".csv");
        for (int n = 0; n < p->GetPoints()->GetNumberOfPoints(); ++n) {
          igtlFloat32 x, y, z;
          p->GetPoints()->GetPoint(n, x, y, z);
          pts << x << "," << y << "," << z << "\n";
        }
      }
    } else if (type == "STRING") {
      igtl::StringMessage::Pointer t = igtl::StringMessage::New();
      crc = receive(s, h, t);
      if (crc) o << "text " << t->GetString() << "\n";
    } else {
      std::vector<char> skip(h->GetBodySizeToRead());
      s->Receive(skip.data(), skip.size());
    }
    o << "crc " << (crc ? "ok" : "failed") << "\n";
  }
  s->CloseSocket();
  return 0;
}
