use ecr_macros::ecr_method;

ecr_method!(r = 99999999999999999999999);

fn main() {}
