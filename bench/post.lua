-- wrk script: POST a scene to /v1/jobs until the queue is full (each thread stops at its first
-- 429), then print accepted/refused counts and the latency percentiles of all POSTs.
local f = assert(io.open(os.getenv("SCENE"), "rb"))
wrk.method = "POST"
wrk.body = f:read("*a")
f:close()
wrk.headers["Content-Type"] = "model/gltf-binary"

local threads = {}

function setup(thread)
   table.insert(threads, thread)
end

function init(args)
   accepted = 0
   refused = 0
   other = 0
end

function response(status, headers, body)
   if status == 202 then
      accepted = accepted + 1
   elseif status == 429 then
      refused = refused + 1
      wrk.thread:stop()
   else
      other = other + 1
   end
end

function done(summary, latency, requests)
   local a, r, o = 0, 0, 0
   for _, t in ipairs(threads) do
      a = a + t:get("accepted")
      r = r + t:get("refused")
      o = o + t:get("other")
   end
   io.write(string.format(
      "POST /v1/jobs until the queue is full: %d accepted (202), %d refused (429), %d other; " ..
      "p50 %.2f ms, p99 %.2f ms, max %.2f ms\n",
      a, r, o, latency:percentile(50) / 1000, latency:percentile(99) / 1000, latency.max / 1000))
end
