src{}
os.execute("touch /tmp/seamcook-sandbox-escaped")
