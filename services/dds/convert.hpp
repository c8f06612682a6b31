#pragma once
// Conversions between the plain structs of common/protocol and the fastddsgen types, one pair per
// row of SYNDDS_DATA_TOPICS and SYNDDS_PROTOCOL_MESSAGES (protocol/messages.hpp). They are built
// from the field lists of the plain structs: a field is copied to and from the IDL member of the
// same name (or the name its field list gives). Incoming samples are validated here: a malformed
// sample raises ProtocolError naming the field.
#include <syndds.h>

#include <optional>

#include "protocol/messages.hpp"

namespace syndds::dds {

#define SYNDDS_DDS_CONVERT_(MSG, IDL)   \
  msg::IDL to_dds(const proto::MSG& m); \
  proto::MSG from_dds(const msg::IDL& m);
#define SYNDDS_DDS_CONVERT_TOPIC_(TOPIC, MSG, IDL, LIST, PER_FRAME) SYNDDS_DDS_CONVERT_(MSG, IDL)
SYNDDS_PROTOCOL_MESSAGES(SYNDDS_DDS_CONVERT_)
SYNDDS_DATA_TOPICS(SYNDDS_DDS_CONVERT_TOPIC_)
#undef SYNDDS_DDS_CONVERT_TOPIC_
#undef SYNDDS_DDS_CONVERT_

/// The generated type of each data topic, and the data topic of each generated type.
template <proto::Topic T>
struct DdsType;
template <typename Dds>
struct DdsTopicOf {
  static constexpr std::optional<proto::Topic> value = std::nullopt;  // not a data topic
};
#define SYNDDS_DDS_TOPIC_(TOPIC, MSG, IDL, LIST, PER_FRAME)   \
  template <>                                               \
  struct DdsType<proto::Topic::TOPIC> {                     \
    using type = msg::IDL;                                  \
  };                                                        \
  template <>                                               \
  struct DdsTopicOf<msg::IDL> {                             \
    static constexpr std::optional<proto::Topic> value = proto::Topic::TOPIC; \
  };
SYNDDS_DATA_TOPICS(SYNDDS_DDS_TOPIC_)
#undef SYNDDS_DDS_TOPIC_

}  // namespace syndds::dds
