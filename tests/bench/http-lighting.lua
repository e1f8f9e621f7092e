-- http-lighting.lua: wrk script for tests/bench/http-bench.sh.
-- redirect=0: the server answers the viewpoint at once (no 307 to its cell URL), as before issue 14.
-- wrk ... -s http-lighting.lua URL -- MODE PATH X Y Z SPREAD [TOKEN]
--   MODE fixed: every request asks for the same viewpoint (a warm cache);
--   MODE vary:  each request moves the viewpoint to a pseudo-random point
--               within +-SPREAD on x and z, so the cache (keyed on the
--               snapped viewpoint) almost always misses.
-- Counts X-GI-Cache values and statuses per thread and prints one line
-- "RESULT key=value ..." that the shell script parses.
local threads = {}

function setup(thread)
  thread:set("id", #threads + 1)
  table.insert(threads, thread)
end

function init(args)
  mode, path = args[1], args[2]
  x, y, z, spread = tonumber(args[3]), tonumber(args[4]), tonumber(args[5]), tonumber(args[6])
  if args[7] and args[7] ~= "" then wrk.headers["Authorization"] = "Bearer " .. args[7] end
  math.randomseed(1000 + id) -- deterministic, but different per thread
  hits, misses, coalesced, other, non200 = 0, 0, 0, 0, 0
  fixed = wrk.format("GET", string.format("%s?redirect=0&at=%.6f,%.6f,%.6f", path, x, y, z))
end

function request()
  if mode == "fixed" then return fixed end
  local dx = (math.random() * 2 - 1) * spread
  local dz = (math.random() * 2 - 1) * spread
  return wrk.format("GET", string.format("%s?redirect=0&at=%.6f,%.6f,%.6f", path, x + dx, y, z + dz))
end

function response(status, headers, body)
  if status ~= 200 then non200 = non200 + 1 end
  local c = headers["X-GI-Cache"] or headers["x-gi-cache"]
  if c == "hit" then hits = hits + 1
  elseif c == "miss" then misses = misses + 1
  elseif c == "coalesced" then coalesced = coalesced + 1
  else other = other + 1 end
end

function done(summary, latency, requests)
  local h, m, c, o, n = 0, 0, 0, 0, 0
  for _, t in ipairs(threads) do
    h = h + t:get("hits"); m = m + t:get("misses"); c = c + t:get("coalesced")
    o = o + t:get("other"); n = n + t:get("non200")
  end
  local secs = summary.duration / 1e6
  local e = summary.errors
  io.write(string.format(
    "RESULT requests=%d duration_s=%.3f rps=%.2f p50_ms=%.3f p90_ms=%.3f p99_ms=%.3f max_ms=%.3f " ..
    "hit=%d miss=%d coalesced=%d no_cache_header=%d non200=%d socket_errors=%d timeouts=%d\n",
    summary.requests, secs, summary.requests / secs, latency:percentile(50) / 1000,
    latency:percentile(90) / 1000, latency:percentile(99) / 1000, latency.max / 1000, h, m, c, o, n,
    e.connect + e.read + e.write, e.timeout))
end
